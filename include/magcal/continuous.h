/**
 * @file continuous.h
 * @brief Continuous 2-D calibrator (issue 13): a calibrator a vehicle runs from power-up for its
 *        whole life. Informative samples go into the intake store (intake.h); the batch solver
 *        (calibrator.h, its algorithms unchanged) runs in slices, one stage per step() call, on a
 *        snapshot of the store; adoption uses the batch never-worse rule plus ageing of the
 *        installed calibration; a persistent mismatch of new samples with the installed
 *        calibration is declared a change and relearned. docs/calibrator.md "Continuous
 *        calibrator" has the state diagram and the maths.
 *
 * Per loop iteration the firmware calls, in any order and as often as it likes:
 *  - magcal_cont_push(): one raw sample and its time stamp (ms). O(1): it only writes into a
 *    MAGCAL_CONT_RING-sample single-producer / single-consumer ring inside the instance.
 *  - magcal_cont_step(): bounded work ("Work per step" below): drains ring samples into the
 *    store (each judged against the installed calibration: trust, change detection), then
 *    continues the solve (the snapshot of the store into the solver buffer, then the solver's
 *    resumable phases, calibrator.h "Time-sliced solve"). Returns MAGCAL_CONT_IN_PROGRESS while a
 *    solve is under way, MAGCAL_CONT_IDLE while collecting, or the outcome of a solve that just
 *    ended.
 *  - magcal_cont_heading(): heading of a raw sample with the installed calibration, its trust and
 *    the generation (adoptions so far).
 *
 * States (no sticky state; every state returns to COLLECTING by itself):
 *  COLLECTING -> SOLVING   when coverage >= cfg.solve_coverage_deg AND at least cfg.min_new
 *                          samples were stored since the last solve (new information), or,
 *                          after a NOT_BETTER verdict, cfg.age_ms / 4 later (the installed
 *                          calibration has aged: the same data are judged with a lower margin);
 *  SOLVING -> COLLECTING   when the solve ends (adopted, refused or failed: collection never
 *                          stops; pushes continue during the solve);
 *  SOLVING -> SOLVING      when the solve found the store INCONSISTENT (two installations: the
 *                          solver's consistency gate, calibrator.h cfg.max_inconsistent_frac):
 *                          the next solve starts at once on the store without its older half
 *                          (docs/calibrator.md "Consistency gate"; the calibration in force and
 *                          the state are untouched);
 *  COLLECTING -> SOLVING   at once, too, when a level shift was declared ("Level shift" below:
 *                          the snapshot drops the samples from before it); a solve that saw the
 *                          store before a shift, or that ends while one is under watch, ends
 *                          SOLVING -> COLLECTING refused (INCONSISTENT, calibration untouched);
 *  any -> RELEARNING       when a change is declared (old samples dropped; with push_g, a sample
 *                          tilted beyond the level limit is no evidence either way while the
 *                          judge has no field model, e.g. under a calibration restored from
 *                          flash: docs/calibrator.md "Stop 28");
 *  (a solve starts at cfg.coarse_coverage_deg instead while no full calibration is installed)
 *  RELEARNING -> SOLVING   as COLLECTING; a solve that adopts, or that confirms the installed
 *                          calibration on fresh data (NOT_BETTER), ends the relearning.
 *
 * Work per step. cfg.step_budget (default MAGCAL_SLICE_BUDGET_DEFAULT = 7500) estimated
 * Cortex-M4F instructions per call, shared by the drain and the solve, every piece of work charged
 * by a weight measured on the target (QEMU, tools/bench/cont_weights.py; docs/performance.md):
 *  - drain: at least one ring sample when the ring is not empty, at most cfg.drain_per_step; a
 *    further one only when no solve is under way and the drain is behind (the ring holds a quarter
 *    of MAGCAL_CONT_RING, or samples parked during the field-model fit are queued) and its charge
 *    fits what is left. Each sample is charged its store push (1200) and its judge (1100, with a
 *    calibration installed). The store's sweep steps (cfg.intake.sweep_steps) run once per step
 *    after the drain, whatever it took (the sweep keeps its pace in time; a catch-up step that
 *    takes two samples does not pay two sweeps): 480 per surveyed slot, 500 per re-bin, the end
 *    of a sweep (its fits, 5500) only as the sweep part's first and only step;
 *  - coverage count (whether a solve is worth it, O(slots)): resumable over bins within what
 *    the drain left, over a few steps (the drain keeps running meanwhile);
 *  - snapshot: the store copied into the solver buffer (whole bins, ~21 per sample; +90 per
 *    sample while the cut of an INCONSISTENT solve is applied); its first
 *    step drains before it copies, then the drain pauses until it is complete so the solver sees
 *    one consistent store;
 *  - solve: the rest of the budget, at most 4/5 of it (its phase weights are estimates), at least
 *    one visit per step (so both progress), then
 *    MAGCAL_IN_PROGRESS until the solve ends. A solve of the default store takes several hundred
 *    steps (docs/calibrator.md); new information for the next solve counts from the snapshot;
 *  - field-model fit: the step that adopts returns MAGCAL_CONT_ADOPTED (cal installed); the judge's
 *    total-field model is then fitted over the store in the following steps (passes charged per
 *    sample, MAGCAL_CONT_IN_PROGRESS, the judge radius-only meanwhile; ~50-70 steps at 288
 *    samples, <= 6.5k M4F each). The store is frozen: ring samples are parked in the solver buffer
 *    (a FIFO of slots / 2) and drained first after the fit, before any new solve.
 * step_budget UINT32_MAX does a whole solve in one call (as solve_blocking()).
 *
 * Coarse calibration (cfg.coarse_coverage_deg, NXP's 4-element stage in 2-D): until a full
 * ellipse is installed, a solve already starts at the coarse coverage; below the solver's 270-deg
 * gate it fits the hard-iron circle only and installs it when its own heading-error bound
 * (calibrator.h "Coarse stage") is within cfg.coarse_max_err_deg. Such a calibration is a
 * generation like any other (step() returns MAGCAL_CONT_ADOPTED, `last.coarse` = 1, cc.cal_coarse
 * = 1), but its headings carry MAGCAL_TRUST_COARSE (not OK: the soft iron is unseen; the bound
 * is in `adopted_err` / last.est_param_err_deg); the next solves (again from the coarse
 * coverage) may replace it by a better coarse one (margin 3) or by a full ellipse over >= 270
 * deg (margin 1: whenever the full one is not estimated worse), which ends the coarse stage for
 * good (a coarse one never replaces a full one). Save to flash only when cc.cal_coarse == 0: a
 * restored calibration is taken as full.
 *
 * Arc calibration (cfg.arc_coverage_deg, opt-in, default 0 = off): until a calibration is
 * installed, a solve already starts at the arc coverage and the solver may install the full
 * ellipse fitted on an arc below its 270-deg gate when its whole-circle bound (calibrator.h "Arc
 * stage": the fit's covariance at 36 headings of the whole circle plus cfg.arc_model_deg) is
 * within cfg.arc_max_err_deg. Marked as a coarse one: `last.arc` = 1, cc.cal_coarse = 2, headings
 * MAGCAL_TRUST_COARSE, the bound in `adopted_err`; a full ellipse over >= 270 deg replaces it with
 * margin 1, an arc or a circle never. Off by default: on the generated drives the bound's model
 * term has to be ~7 deg to cover the truth, and the loop after an arc adoption was worse
 * (docs/calibrator.md "Arc stage").
 * Offset-only relearn (cfg.offset_coverage_deg, default 180; docs/calibrator.md "Offset-only
 * relearn"): after a declared change, while RELEARNING with a full calibration installed (not a
 * coarse one, not one restored from flash: its own error is unknown), a solve already starts at
 * that live coverage and refits only the hard iron (centre and radius) under the installed
 * soft-iron shape, time-sliced over the snapshot like the solver. It is installed (a generation,
 * MAGCAL_CONT_ADOPTED, trust OK, cc.cal_offset = 1) when its bound on the heading error over the
 * whole circle (the centre's covariance, the fresh samples' 2nd harmonic, the installed
 * calibration's own estimate) is within cfg.offset_max_err_deg; MAGCAL_ERR_SHAPE_CHANGED when the
 * installed shape no longer explains the fresh samples (residual sigma above cfg.offset_sigma_ratio
 * x the installed one's, a significant 2nd harmonic, the radius moved): no further offset fit until
 * the next change, the full solve relearns. The full solve replaces it later by the usual rules.
 *
 * Level shift (cfg.shift_rel, default 0.25; docs/calibrator.md "Level shift"): while no
 * calibration is installed nothing judges the stream, and a store that spans a change of the
 * installation (a magnet attached before the first calibration) can hold two rings that a single
 * ellipse bends to fit (the consistency gate's known gap). A vehicle turns its field smoothly (at
 * 50 Hz under 0.03 R per sample); a hard-iron step moves it at once. The drain watches every
 * sample: an isolated jump (more than 0.15 R between samples at most 250 ms apart, and 4x the
 * increments before and after it: a turn at any rate moves by similar increments) opens an
 * episode; the jumps' vectors are summed (a glitch or a stepped transient undoes its own jump),
 * and when cfg.shift_hold_ms pass without a further jump a sum above cfg.shift_rel x R and half
 * the largest jump is a level shift: the next snapshot drops every stored sample older than the
 * episode's first jump, a solve under way when it was declared is refused
 * (MAGCAL_ERR_INCONSISTENT, the calibration untouched), and so is a solve that ends while the
 * open episode's sum already reads as a shift. R is the watch's own scale: an average of the
 * samples' distance from the store's centre (the store's radius can be far off before a
 * calibration); samples beyond 4 R are no positions, and they, a gap in the stamps, or the end of
 * the chain void an open episode. With no episode open, a burst of non-positions up to 1 s long
 * (a glitch burst, a sensor saturated while a magnet came near it) is bridged: the jump from the
 * last position before it to the first after it is a candidate when it is more than 0.15 R and
 * more than a turn at 30 deg/s (or a steady motion at the typical increment) moves the field in
 * that time. Counted in cc.shifts, cc.shift_refused. Not seen: a change slower than 0.15 R per
 * sample (a magnet brought in over a second at 50 Hz), one inside a longer burst or a gap, or
 * inside a burst that follows an open episode; those fall back on the consistency gate.
 *
 * Tilt in the estimate (cfg.tilt_model_deg, default 4.5; docs/calibrator.md "Tilt in the
 * estimate"): a store filled on hills and not levelled (push_g's vertical field not learnt, or
 * learnt after the samples were stored) bends the ellipse by the tilt's leak, which the fit's own
 * estimate cannot see (generated drives: 3.9..6.2 deg true error at level with estimates of
 * 0.3..1.05 when all the inliers were tilted). With push_g's gravity, the full solve's
 * est_param_err_deg (and est_heading_err_deg, the never-worse rule, `adopted_err`) takes
 * cfg.tilt_model_deg x the share of the snapshot's samples that are not LEVEL, in quadrature;
 * without gravity (magcal_cont_push) nothing is known of the tilt and no term is added. The term
 * is an average: a store on one constant slope is off by more (7.4 deg on a 5-deg slope in the
 * Unity test, estimate 4.5).
 *
 * Continuity gate (cfg.continuity, opt-in, default 0 = off; docs/calibrator.md "Continuity
 * gate"): before a calibration judges the stream, nothing tells a driver's garbage burst
 * (readings anywhere in the sensor's range, 5..40 in a row) from data, and a store holding more
 * garbage than field (a vehicle parked at start fills one bin) gives the survey a garbage centre
 * and radius that then keep every new sample out (the 60-min seed-7 drive: centre (332, -55),
 * radius 359 for a ring of 21 at (18, -11), no solve in 60 minutes). With the gate on, the drain
 * stores a sample only when it lies within 6x the stream's typical increment per sample of the
 * last stored one (the typical increment: an average of squared increments, each counted at most
 * 4x the average: a burst cannot teach it, a turn starting from rest does within about 12
 * samples); 8 refused samples in a row that move as a stream start it again (a lasting jump is
 * not refused for ever); the first sample after a start is not stored, after a stamp gap
 * (> 250 ms) not judged. cc.cg_refused counts the samples kept out. Off by default: on the
 * generated drives it made 4 of 6 60-min drives that never adopted adopt, but moved the solves
 * of the others onto stores whose tilt leak is larger (trusted RMS / floor 60-min s3 1.18 ->
 * 1.31, 30-min s1 0.25 -> 2.09): docs/calibrator.md "Continuity gate".
 *
 * Tilt compensation (magcal_cont_push_g, cfg.tilt_comp_deg; docs/calibrator.md "Tilt
 * compensation"). A pitch p (roll r) shifts the body's horizontal field by Z (sin r, sin p) to
 * first order (Z: the body's vertical field), i.e. the raw x, y by k t with t = (g_x, g_y) / g_z of
 * the smoothed gravity and k = Z in raw units: at 6 deg about 12 deg of heading when heading
 * east or west, which a store filled on hills bakes into the calibration. push_g learns k from
 * the stream by a within-sector regression: in each 10-degree heading sector around the store's
 * centre the distance from the centre is a_sector + k q, q = t . radial (a tilt along the field
 * changes the radius; across it, the heading: the error the store must not take); every sample
 * whose tilt moved by 0.3 deg since its sector's last one counts (running means per sector, sums
 * over all; circles on one slope teach nothing: their q moves with the heading only). A sample is
 * refused while the transient judge flags the stream, when its raw z moved by more than 1.5 R |q|
 * from its sector's mean (a disturbance arriving with a change of tilt), and, once k is valid,
 * when it is off the estimate (before that only beyond |k| = 3 R: a wrong early estimate must not
 * gate the truth out); the sectors' means are dropped at a change or a new centre. Raw z must
 * confirm the tilt: a real tilt along the field moves it by -R q, a vehicle's acceleration read
 * as tilt (braking, a hill start) moves nothing, so the slope of z on q over -R (tc_rho: 1 +- the
 * z axis's scale on level-road data, about 0 when accelerations make the tilt) must be within
 * 0.5..2. Once k is known (24 samples, standard error <= 0.12 R, rho), every sample (while k
 * stays known) with a steady |g|, its roll within cfg.intake.tilt_limit_deg (a turn's
 * centripetal acceleration reads as roll: not levelled) and its pitch within cfg.tilt_comp_deg is
 * queued levelled and LEVEL: h' - k t + (h' . t) t / 2 for x, y (h' = m_xy - centre: the level
 * horizontal field to third order) and (m_z + t . h') (1 - t^2 / 2) for z (the tilt turns the
 * horizontal field into z too, so the store's level model of z and the judge's z channel see a
 * level sample). The k samples are levelled with (tc_kl) follows the estimate; under a
 * calibration fitted on levelled samples only once the estimate moved by 5 % (the samples it
 * judges and stores stay levelled as its own were). magcal_cont_heading levels its sample with the gravity of the last
 * push_g the same way, for its heading (hd.levelled = 1: tilt-compensated, fitted and applied on
 * levelled samples alike) and its judge.
 * When k becomes known under a calibration fitted on unlevelled samples (adopted before, or
 * restored at init), step empties the store between solves so that it refills levelled (a
 * relevel, cc.relevels); the calibration stays in force, judged on the samples as they were
 * pushed (un-levelled), until a solve on the levelled store adopts a levelled calibration or
 * confirms it. Its heading stays unlevelled, except when it was adopted here on one slope (the
 * mean tilt of its store's samples known from >= 64 of them, cc.cal_tx / cal_ty, with a spread
 * cc.cal_ts <= 1.1 deg): its centre is then the level one moved by k t_cal, so the heading levels
 * its sample and moves it by as much at once (cc.cal_conv, counted in cc.levels); a confirming
 * solve moves the record's centre.
 * Across a power cycle: magcal_cont_tilt_state gives k and whether the installed calibration is
 * levelled, to keep in the flash record with it (record.h tilt_k, tilt_levelled);
 * magcal_cont_restore_tilt after magcal_cont_init puts them back, so samples are levelled from
 * the first push_g and a levelled calibration is judged on levelled samples at once (a calibration
 * restored without them reads the hills of a road as a lasting mismatch and declares a change
 * within minutes: docs/calibrator.md).
 * The model takes the specific force for gravity: a vehicle's longitudinal acceleration reads as
 * pitch (it is not levelled only when |g| leaves its g_band_rel band).
 *
 * OK tolerance (cfg.ok_max_err_deg, default 3; 0 = off). A heading is OK only under a full
 * calibration whose own error estimate is within the tolerance: `adopted_err`, the adopting
 * solve's est_heading_err_deg (per-sample noise, parameter error and the tilt term of "Tilt in
 * the estimate"), then after every later full solve that keeps it (NOT_BETTER) the error that
 * solve measured for it on its fresh data combined with its own estimate (the measure is only
 * as good as its reference), sqrt(current_err_deg^2 + est_heading_err_deg^2). Above the
 * tolerance its headings are MAGCAL_TRUST_COARSE: installed and usable, not the OK promise. (48
 * generated 30-min drives: every calibration adopted with an estimate over 3 deg had OK rows
 * more than 5 deg off, 6,127 rows on seed 35 at an estimate of 4.4 deg; docs/calibrator.md.) A
 * calibration restored from flash has no estimate (NaN) and is not held by the tolerance; one
 * levelled at once by k times its fit tilt (a relevel, "Tilt compensation") drops the tilt term
 * ("Tilt in the estimate") from its estimate: the levelling removes what the term stood for.
 * The estimate and the tilt's predicted error ("Tilt in the trust"; without gravity the slopes'
 * measure, "Slopes without gravity") add up: a heading whose two sum to more than 1.2 x the
 * tolerance is MAGCAL_TRUST_TILTED, though each is within its own (an estimate of 2.9 deg and
 * 2.9 deg of tilt left headings OK 7 deg off: 30-min seed 20 in a variant of stop 34;
 * docs/calibrator.md "Stop 34"). With cfg.tilt_trust_deg 0 this sum is off too.
 * For the first second after every install (and every field-model fit) the transient judge
 * restarts its baselines and can raise no flag: its headings are COARSE then, not OK (30-min
 * seed 34: a transient that began 0.3 s before a relearn's install was OK up to 14.2 deg off).
 * Known gap: a transient under way at an install can still be OK far off. Its rise is learnt by
 * the heading regression in that second and explained away (0..0.1 s before), or has entered
 * the restarted baselines (0.4 s or more before); tests/test_cont_trust_gaps.c prints up to
 * 22 OK rows beyond 5 deg, 14.6 at worst, for a 15-deg, 8 % transient (docs/calibrator.md
 * "Stop 35").
 *
 * Tilt in the trust (cfg.tilt_trust_deg, default 3; 0 = off). A 2-D calibration is right only at
 * the tilt it was fitted at. With push_g's gravity, magcal_cont_heading predicts the heading
 * error of the current tilt t against the calibration's fit tilt t_cal (0 for one fitted on, or
 * levelled to, levelled samples; a levelled heading's t is 0): |k| |t - t_cal| / R rad, with k the
 * compensation's when valid, else 2.5 R (an inclination of 68 deg). For a calibration fitted on
 * unlevelled samples the spread s of their tilts (RMS about t_cal) counts too, |k| sqrt(|t -
 * t_cal|^2 + s^2) / R: a store whose sectors were filled at different tilts bends the ellipse,
 * which no single tilt undoes (30-min seed 14: s 1.5 deg, 920 headings OK at 4.4 deg RMS before
 * the spread term). A stored sample whose gravity gave no tilt (|g| unsteady, beyond the limits:
 * a turn, braking) counts in t_cal and s with the tilt known 1..2 s before the last one (not the
 * acceleration ramping in), so a store filled in turns under the car's own acceleration still has
 * a known fit tilt. Above cfg.tilt_trust_deg the heading is MAGCAL_TRUST_TILTED, not OK. When the
 * regression shows the accelerometer's tilt to be mostly acceleration (rho < 0.5) the tilt it
 * reads still counts (it may be a road's; while the gravity of now gives none, the last tilt
 * known), and so does the one held from 1..2 s before, whichever predicts more. Nothing is
 * predicted (the trust is the judge's alone) while |g| is unsteady or the roll
 * beyond cfg.intake.tilt_limit_deg (a turn) or the pitch beyond cfg.tilt_comp_deg before the
 * regression has shown acceleration. A calibration restored without its tilt state (its fit tilt
 * unknown) is taken as a level one (t_cal 0; restored levelled with magcal_cont_restore_tilt its
 * headings are levelled too).
 *
 * Slopes without gravity (src/loop/cont_slope.c). A calibrator that never had a gravity (push
 * alone) cannot level, and a slope p moves its heading by up to tan(inclination) p (2 p at 64 deg;
 * 48 generated 30-min drives with +-6 deg hills replayed without gravity: 228,524 of 784,750 OK
 * rows more than 5 deg off, 46.7 at worst). Raw z sees a slope too, except at the headings where
 * it moves the heading most (a pitch at east or west), so the library measures the roads: raw z
 * about its level (the store's fit against the heading's cos and sin: the soft iron's leak), the
 * store's median spread (in a pass of the field-model fit), the spread of the last 2 minutes, the
 * largest over the last half hour and the last slope raw z showed (held over a minute).
 * tan(inclination) taken as 2.5 (k / R unknown without gravity) times twice the largest of them is
 * the heading error the slopes can cause: above cfg.tilt_trust_deg the heading is
 * MAGCAL_TRUST_TILTED, and so it is until the field-model fit after the first install has
 * measured the store and 2 s more (2 minutes when the store itself shows slopes). On the same
 * drives: 8,586 OK rows, 345 beyond 5 deg (7.2 at worst: a calibration fitted on slopes, off on
 * the flat, which no measure of now sees). Hills of +-2 deg: 36,013 -> 1,815 of 126,535; flat:
 * 394 -> 377 of 822,517 (not slopes: hard-iron steps no judge saw without gravity), 5.2 % fewer OK
 * rows than before. OK headings on slopes need gravity (push_g): the same 48 hilly drives with
 * gravity keep 658,533 OK rows, 275 beyond 5 deg, and are unchanged by this measure (it runs only
 * while no gravity ever came).
 *
 * Gyro heading check (cfg.rate_trust_deg, default 2.5; 0 = off; magcal_cont_push_imu). A
 * magnetometer alone reads the onset of a disturbance across the field as a turn: the heading
 * moves at first order, the field magnitude the judge watches at second. With the gyro's rates,
 * each sample is queued with the rotation about the up axis (along push_g's smoothed gravity, else
 * body z) since the sample before (trapezoid; unknown after a gap of MAGCAL_CONT_RATE_GAP_MS or a
 * sample of push or push_g), and the drain carries a track of the corrected heading on it, pulled
 * towards the magnetic heading by a proportional-integral loop (10-s natural frequency; its
 * integral is the gyro's bias, so an uncalibrated gyro is fine). A heading that leaves the track
 * by more than cfg.rate_trust_deg (or 4 x the track's RMS deviation on clean samples) is
 * MAGCAL_TRUST_DISTURBED; meanwhile, and under a glitch or a transient flag, the track coasts on
 * the gyro; a deviation that lasts 8 s is no transient and the track restarts at the magnetic
 * heading (a lasting change is the change detection's). The track restarts at every new
 * calibration, relearn and gap, and at a sample whose magnetic and gyro moves disagree by more
 * than 5 deg (a glitch of either sensor). The check starts after 60 s of judged samples (the bias
 * settled). The sign between the gyro's rotation and the heading is the contract's (w in m's
 * right-handed axes: a positive rotation about up turns the heading anticlockwise) and checked on
 * every 180 deg of turning: a gyro frame mirrored against the magnetometer's is turned to (with a
 * new warm-up). It affects the trust only: a flagged sample is still judged and stored by the
 * magnitude judge's rules. docs/calibrator.md "Gyro heading check".
 *
 * Gyro-aided gravity (cfg.gyro_gravity, default 0: opt-in; magcal_cont_push_imu). A car's accelerometer
 * reads its acceleration too: a turn's centripetal 0.2 g reads as 11 deg of roll, braking as
 * pitch, and a heading levelled or judged with it is off by degrees. push_imu carries the up
 * direction on the gyro's rates (du/dt = u x w, w in the accelerometer's right-handed axes) and
 * pulls it towards the smoothed accelerometer (0.5 s) only where that reads gravity alone: its
 * magnitude within 0.3 % of its running level, the rate about up below 1 deg/s (no turn, no
 * centripetal acceleration) and, once locked, within 1.5 deg of the estimate (a gentle
 * acceleration: the gyro saw no pitch). The pull's integral is the gyro's bias (no gyro
 * calibration needed). It locks after 30 s of consistent pulls (acquisition gains meanwhile: a
 * car standing or driving straight at power-up), loses the lock after 10 s of pulls all beyond
 * 1.5 deg, and restarts at a gap of 250 ms in the rates or a rate across up beyond 60 deg/s (a
 * gyro glitch). Locked, push_g takes the estimate wherever the smoothed accelerometer is more
 * than 1 deg from it or 2 % off its level (turns, braking); elsewhere the accelerometer (it is
 * then the better of the two); unlocked, always the accelerometer. Locked, the tilt
 * compensation's k learns only from samples whose accelerometer is within 0.3 deg of the
 * estimate (an acceleration inside the 1-deg window biases k towards 0). A steady circle has no
 * straight to lock on: its centripetal acceleration stays what push_g's tests make of it.
 * docs/calibrator.md "Gyro-aided gravity".
 *
 * Concurrency contract. magcal_cont_push() may run in an interrupt (or another task) while ANY
 * other call on the same instance runs in one task: the ring is the only state push writes
 * (its head index, after the sample; step only writes the tail index; magcal_cont_push_g also
 * writes its gravity classifier's and tilt compensation's state, which nothing else writes, and
 * reads the store's centre, radius and centre generation and the instance's change count,
 * calibration flags (has_cal, cal_lv), transient flag and state, which step writes: a torn read
 * misplaces one sample of k's fit or delays the switch-on by one sample; magcal_cont_push_imu
 * writes its rate state (gy_*, ga_*) and the ring's rotations, which nothing else writes, and is
 * push_g otherwise: the three push calls are one producer). Everything else (step,
 * solve_blocking, heading, progress, status, reset) must run in ONE task context (not
 * concurrently with each other). Two push callers on one instance need the caller's own lock.
 * When the ring is full the sample is dropped and counted (MAGCAL_ERR_BUFFER_FULL). The index
 * handover uses MAGCAL_CONT_BARRIER() (a compiler + hardware memory barrier on GCC/Clang).
 *
 * Memory: caller-owned store slots MAGCAL_CONT_SLOTS(sectors, per_bin), solver buffer of as many
 * magcal_vec2_t, and a solver workspace of MAGCAL_CONT_WORKSPACE_LEN(sectors, per_bin) bytes.
 *
 * @code
 * #include "magcal/continuous.h"
 * #define SLOTS MAGCAL_CONT_SLOTS(36u, 8u)
 * static magcal_intake_slot_t slots[SLOTS];
 * static magcal_vec2_t solve_buf[SLOTS];
 * static MAGCAL_CALIBRATOR_WORKSPACE_DECLARE(work, SLOTS);
 * static magcal_cont_t cc;
 * void init(const magcal_cal2d_t *from_flash) {
 *     magcal_cont_cfg_t cfg = MAGCAL_CONT_CFG_DEFAULT;
 *     (void)magcal_cont_init(&cc, &cfg, from_flash, slots, SLOTS, solve_buf, work, sizeof work);
 * }
 * void mag_isr(magcal_vec3_t m, uint32_t now_ms) { (void)magcal_cont_push(&cc, &m, now_ms); }
 * void control_task_100hz(magcal_vec3_t raw) {
 *     magcal_cont_heading_t hd;
 *     if (magcal_cont_step(&cc) == MAGCAL_CONT_ADOPTED && cc.cal_coarse == 0u) { save_to_flash(&cc.cal); }
 *     if (magcal_cont_heading(&cc, &raw, 0.0f, &hd) == MAGCAL_OK && hd.trust == MAGCAL_TRUST_OK) {
 *         use(hd.heading_deg);
 *     }
 * }
 * @endcode
 */
#ifndef MAGCAL_CONTINUOUS_H
#define MAGCAL_CONTINUOUS_H

#include <stddef.h>
#include <stdint.h>

#include "magcal/calibrator.h"
#include "magcal/config.h"
#include "magcal/heading.h"
#include "magcal/intake.h"
#include "magcal/status.h"
#include "magcal/types.h"

#ifdef __cplusplus
extern "C" {
#endif

#ifndef MAGCAL_CONT_RING
#define MAGCAL_CONT_RING 32u /**< push ring: samples (power of two) */
#endif

#define MAGCAL_CONT_TC_BINS 36u  /**< magcal_cont_push_g tilt compensation: heading sectors of its regression */

#ifndef MAGCAL_CONT_G_SMOOTH_MS
#define MAGCAL_CONT_G_SMOOTH_MS 500u /**< magcal_cont_push_g: time constant of the gravity smoothing, ms */
#endif
#ifndef MAGCAL_CONT_G_TAU_MS
#define MAGCAL_CONT_G_TAU_MS 10000u /**< magcal_cont_push_g: time constant of the |g|^2 level, ms */
#endif
#define MAGCAL_CONT_RATE_GAP_MS 250u /**< magcal_cont_push_imu: a longer gap between rates leaves the
                                          rotation since the sample before unknown */
#define MAGCAL_CONT_RATE_MAX_DPS 4000.0f /**< magcal_cont_push_imu: a rate beyond this (deg/s) is no
                                              reading: the rotation through it is unknown */

#ifndef MAGCAL_CONT_BARRIER
#if defined(__GNUC__) || defined(__clang__)
#define MAGCAL_CONT_BARRIER() __atomic_thread_fence(__ATOMIC_SEQ_CST)
#else
#define MAGCAL_CONT_BARRIER() ((void)0) /**< define it for your compiler (a full memory barrier) */
#endif
#endif

/** Store slots = solver buffer samples of a configuration (2-D intake: sectors x per_bin). */
#define MAGCAL_CONT_SLOTS(sectors, per_bin) MAGCAL_INTAKE_SLOTS_2D(sectors, per_bin)
/** Solver workspace bytes. */
#define MAGCAL_CONT_WORKSPACE_LEN(sectors, per_bin)                                                \
    MAGCAL_CALIBRATOR_WORKSPACE_LEN(MAGCAL_CONT_SLOTS(sectors, per_bin))

/** Lifecycle state. */
typedef enum {
    MAGCAL_CONT_COLLECTING = 0, /**< collecting; a solve starts when worth it */
    MAGCAL_CONT_SOLVING = 1,    /**< a sliced solve is under way (pushes continue) */
    MAGCAL_CONT_RELEARNING = 2  /**< a change was declared: collecting fresh data */
} magcal_cont_state_t;


/** Outcome of step(). */
typedef enum {
    MAGCAL_CONT_IDLE = 0,        /**< collecting, no solve under way */
    MAGCAL_CONT_IN_PROGRESS = 1, /**< a solve is under way: call step() again */
    MAGCAL_CONT_ADOPTED = 2,     /**< a solve ended and installed a new calibration */
    MAGCAL_CONT_REFUSED = 3,     /**< a solve passed the gates but the installed one was kept */
    MAGCAL_CONT_FAILED = 4,      /**< a solve failed a gate (status in magcal_cont_status) */
    MAGCAL_CONT_CHANGE = 5       /**< a change was declared during this step's intake */
} magcal_cont_outcome_t;

/** Configuration: start from MAGCAL_CONT_CFG_DEFAULT. */
typedef struct {
    magcal_intake_cfg_t intake;     /**< store (2-D; default MAGCAL_INTAKE_CFG_DEFAULT_2D) */
    magcal_calibrator_cfg_t solver; /**< batch solver (MAGCAL_CALIBRATOR_CFG_STORE_DEFAULT) */
    float solve_coverage_deg;       /**< live coverage that starts a solve (default 280: one 10-degree sector above the
                                         solver's 270 gate, the live estimate's error; a sliced solve that
                                         fails COVERAGE costs ~1000 steps) */
    uint16_t min_new;               /**< samples stored since the last solve to start one (default 24) */
    uint16_t drain_per_step;        /**< ring samples moved into the store per step, >= 1 (default 4) */
    float age_ms;                   /**< ageing: the adoption margin falls from
                                         MAGCAL_CALIBRATOR_ADOPT_MARGIN towards 1 as
                                         1 + (margin - 1) / (1 + t / age_ms), t = ms of push
                                         stamps since the installed calibration's adoption (or
                                         init) (default 600000: 10 min to margin 2) */
    float mismatch_k;               /**< sample mismatch: | |h| / R - 1 | > max(k sigma, min) (default 4) */
    float mismatch_min_rel;         /**< floor of that threshold (default 0.06) */
    uint32_t change_ms;             /**< mismatch time of an open episode to declare a change (8000) */
    uint16_t change_bins;           /**< distinct 10-degree sectors an episode must span (default 3) */
    uint32_t clear_ms;              /**< consistent time that closes an episode (default 4000) */
    uint32_t disturb_tau_ms;        /**< transient judge: time constant of the smoothed residual (100) */
    uint32_t disturb_hold_ms;       /**< transient judge: flag held after the residual returns (200) */
    float disturb_k;                /**< transient judge: flag at |smoothed - baseline| (less what the heading's
                                         move explains) > k x its RMS on clean samples (4) */
    uint32_t step_budget;           /**< work per step(), estimated Cortex-M4F instructions, >= 1
                                         (default MAGCAL_SLICE_BUDGET_DEFAULT = 7500; UINT32_MAX:
                                         a whole solve per step): "Work per step" above */
    float coarse_coverage_deg;      /**< coarse stage ("Coarse calibration" above): while no full
                                         calibration is installed, a solve starts at this live
                                         coverage and may install a hard-iron-only circle
                                         (calibrator.h "Coarse stage"); 0 = off, else <=
                                         solve_coverage_deg (default 150) */
    float coarse_max_err_deg;       /**< its tolerance: the circle's bound on its heading error
                                         over the whole circle (report est_param_err_deg), > 0
                                         (default 4) */
    float tilt_comp_deg;            /**< magcal_cont_push_g tilt compensation ("Tilt compensation"
                                         below): a sample whose smoothed gravity is pitched by at
                                         most this many degrees (its roll within
                                         cfg.intake.tilt_limit_deg, |g| steady) is levelled before
                                         it is stored, once the vertical field is estimated;
                                         0..30, 0 = off (default 8: the road's 6 deg and margin) */
    float disturb_onset;            /**< transient judge, heading trust only: magcal_cont_heading also
                                         tests its own sample (the drain is a row or more behind) and
                                         flags it DISTURBED from this fraction of the transient
                                         judge's thresholds on (the store's decisions keep the full
                                         thresholds); (0, 1], 1 = the same thresholds (default 0.7:
                                         docs/calibrator.md "Judge and change detection") */
    float arc_coverage_deg;         /**< arc stage ("Arc calibration" above): while no calibration is
                                         installed, a solve starts at this live coverage and may
                                         install a full ellipse fitted on an arc below the solver's
                                         270-deg gate when its whole-circle bound holds
                                         (calibrator.h "Arc stage"); 0 = off, else <=
                                         solve_coverage_deg */
    float arc_max_err_deg;          /**< its tolerance: the ellipse's bound on its heading error over
                                         the whole circle (report est_param_err_deg), > 0 */
    float arc_model_deg;            /**< the bound's model-error term (what an arc cannot see:
                                         a tilt or vertical-field leak the fit absorbs), >= 0 */
    float offset_coverage_deg;      /**< offset-only relearn ("Offset-only relearn" below): while
                                         RELEARNING with a full calibration installed, a solve
                                         already starts at this live coverage and fits the hard
                                         iron only under the installed soft-iron shape; 0 = off,
                                         else 0..360 (default 180: on the generated
                                         drives 150 adopted on seed 30-5 but refused seed 60-1,
                                         180 the reverse; 60-1's fit was the better one) */
    float offset_max_err_deg;       /**< its tolerance: the fit's bound on its heading error over
                                         the whole circle (report est_param_err_deg), > 0
                                         (default 3) */
    float offset_sigma_ratio;       /**< its shape test: the fresh samples' residual sigma around
                                         the installed shape may be at most this multiple of the
                                         installed calibration's, >= 1 (default 2) */
    float shift_rel;                /**< level-shift watch ("Level shift" below): while no calibration
                                         is installed, jumps of the raw field (each > 0.15 R between
                                         samples <= 250 ms apart) that add up to more than this x R
                                         and are not undone within shift_hold_ms mark a change of the
                                         installation: the store's older samples are dropped; 0 =
                                         off, else 0.15..2 (default 0.25) */
    uint32_t shift_hold_ms;         /**< the hold: ms of stamps after the last jump before a shift
                                         is declared (longer than a transient: default 6000), >= 1 */
    float tilt_model_deg;           /**< tilt in the estimate ("Tilt in the estimate" below): with
                                         push_g's gravity, this x the share of the solve's samples
                                         that are not level is added in quadrature to the full
                                         solve's est_param_err_deg (and the never-worse rule);
                                         >= 0, 0 = off (default 4.5) */
    uint8_t continuity;             /**< continuity gate ("Continuity gate" below): 1 = while no
                                         calibration judges the stream (none installed, or a
                                         relearn), a sample that moved from the one before it by
                                         more than 6x the stream's typical increment is not stored;
                                         0 = off (default 0: "Continuity gate" below) */
    float tilt_trust_deg;           /**< tilt in the trust ("Tilt in the trust" below): with push_g's
                                         gravity, a heading whose sample is tilted away from the
                                         calibration's fit tilt by enough to move it by more than
                                         this many degrees is MAGCAL_TRUST_TILTED; >= 0, 0 = off
                                         (default 3) */
    float rate_trust_deg;           /**< gyro heading check ("Gyro heading check" below): with
                                         magcal_cont_push_imu's rates, a heading whose magnetic
                                         move leaves the gyro's track by more than this many
                                         degrees (or 4x the track's RMS deviation) is
                                         MAGCAL_TRUST_DISTURBED; >= 0, 0 = off (default 2.5) */
    float ok_max_err_deg;           /**< the OK tolerance ("OK tolerance" below): headings of a full
                                         calibration whose error estimate (`adopted_err`) is above
                                         this many degrees are MAGCAL_TRUST_COARSE, not OK; >= 0,
                                         0 = off (default 3) */
    uint8_t gyro_gravity;           /**< gyro-aided gravity ("Gyro-aided gravity" below): 1 = with
                                         magcal_cont_push_imu's rates, the gravity push_g levels
                                         and judges with is carried by the gyro and pulled towards
                                         the accelerometer only where it reads gravity alone;
                                         0 = the accelerometer's (default 0, opt-in: on two of
                                         the eight generated drives without vehicle dynamics it
                                         cost every OK heading, docs/calibrator.md; on for a
                                         road vehicle) */
} magcal_cont_cfg_t;

/** An open change episode with at least this much mismatch (ms) holds every heading DISTURBED,
 *  also the samples consistent by chance (src/loop/cont_life.c): longer than a transient (2..5 s;
 *  at 3000 a 3-s transient held the clean rows after it), shorter than cfg.change_ms. */
#define MAGCAL_CONT_EPISODE_TRUST_MS 5000u
/** Bins of the store's histogram of raw z about its level ("Slopes without gravity"). */
#define MAGCAL_CONT_SL_BINS 16u

/** Defaults: work untuned from 10 to 100 Hz (time constants are in ms of the push stamps). */
#define MAGCAL_CONT_CFG_DEFAULT                                                                    \
    {                                                                                              \
        MAGCAL_INTAKE_CFG_DEFAULT_2D, MAGCAL_CALIBRATOR_CFG_STORE_DEFAULT, 280.0f, 24u, 2u,        \
            600000.0f, 4.0f, 0.06f, 8000u, 3u, 4000u, 100u, 200u, 4.0f,                            \
            MAGCAL_SLICE_BUDGET_DEFAULT, 0.0f, 15.0f, 8.0f, 0.7f, 0.0f, 10.0f, 7.0f, 180.0f, 3.0f, 2.0f, \
            0.25f, 6000u, 4.5f, 0u, 3.0f, 2.5f, 3.0f, 0u                                           \
    }

/** A heading with its trust. */
typedef struct {
    float heading_deg;          /**< [0, 360), calibrated (raw when uncalibrated) */
    float raw_heading_deg;      /**< raw axes */
    magcal_trust_state_t trust;  /**< trust state (heading.h: the states magcal_heading_get_trusted() uses) */
    uint32_t generation;        /**< adoptions so far (0 = none) */
    float radius_rel;           /**< |h| / R - 1 under the installed calibration (NaN if none) */
    uint8_t levelled;           /**< 1: heading_deg is tilt-compensated (the sample levelled under the
                                     last magcal_cont_push_g's gravity, "Tilt compensation") */
} magcal_cont_heading_t;

/** Live progress. */
typedef struct {
    magcal_cont_state_t state;  /**< lifecycle */
    float coverage_deg;         /**< store coverage (intake.h definition) */
    float completion_pct;       /**< store completion */
    float missing_start_deg;    /**< longest empty run */
    float missing_width_deg;    /**< its width */
    uint32_t stored;            /**< samples in the store */
    uint32_t new_since_solve;   /**< samples stored since the last solve */
    uint32_t generation;        /**< adoptions so far */
    uint32_t solves;            /**< solves finished */
    uint32_t changes;           /**< changes declared */
    uint32_t dropped;           /**< ring overflows */
    uint8_t episode_open;       /**< 1 while a mismatch episode is open */
} magcal_cont_progress_t;

/** Instance (allocate statically). Fields private except `cal` (read-only: installed calibration)
 *  and `last` (read-only: report of the last finished solve). */
typedef struct {
    magcal_cont_cfg_t cfg;
    uint32_t magic;
    magcal_intake_t store;
    magcal_calibrator_t solver;
    magcal_vec2_t *buf;
    size_t slots;
    magcal_cal2d_t cal;            /**< read-only: installed calibration (IDENTITY until one) */
    magcal_cal_report_t last;      /**< read-only: report of the last finished solve */
    float cal_raw_radius;          /* raw-unit radius of the installed ellipse */
    float cal_sigma_rel;           /* its per-sample relative noise */
    uint8_t has_cal;
    uint8_t state;
    uint8_t stage;                 /* next solve stage, 0 = none */
    magcal_cont_outcome_t last_outcome;
    magcal_status_t last_status;
    uint32_t generation;
    uint32_t solves;
    uint32_t changes;
    uint32_t stored_at_solve;      /* store added + replaced (its counters) at the last solve */
    uint32_t stored_at_adopt;
    uint32_t age_ms_acc;
    uint32_t solve_ms_acc;         /* ms of stamps since the last solve finished */           /* ms of stamps since the installed calibration was adopted */
    magcal_cal2d_t cand;           /* calibration passed to the adopt stage */
    /* ring (push writes ring[head % N] then head; step reads then writes tail) */
    magcal_vec3_t ring[MAGCAL_CONT_RING];
    uint32_t ring_t[MAGCAL_CONT_RING];
    uint8_t ring_tilt[MAGCAL_CONT_RING]; /* magcal_intake_tilt_t of each ring sample (push_g) */
    magcal_vec3_t ring_tl[MAGCAL_CONT_RING]; /* push_g: the tilt (x, y: g_x / g_z, g_y / g_z) of each ring
                                                sample, z = 1 when known (0: unknown, push) */
    magcal_vec3_t g_s;             /* push_g (written by push only): smoothed gravity */
    float g_level2;                /* push_g: running level of |g_s|^2 (0: none yet) */
    uint32_t g_t;                  /* its last stamp */
    volatile uint32_t g_pushed;    /* samples pushed with a finite gravity vector */
    volatile uint32_t g_level;     /* of those, classified LEVEL */
    uint32_t park_lv[(MAGCAL_MAX_SAMPLES / 2u + 31u) / 32u]; /* level bits of the parked FIFO (cont_step.c) */
    uint8_t park_tilt;             /* tilt code of park_m (cont_step.c) */
    uint8_t j_tilted;              /* the drained sample as judged: tilted beyond the level limit (cont_step.c) */
    volatile uint32_t head;
    volatile uint32_t tail;
    volatile uint32_t dropped;
    /* change detection */
    uint32_t last_t;
    uint8_t have_t;
    uint8_t episode_open;
    uint8_t last_mismatch;
    uint32_t mis_ms;
    uint32_t clean_ms;
    uint32_t mis_bins[2];          /* 36 sector bits of the open episode (corrected heading) */
    uint8_t change_flag;           /* a change was declared in the current step */
    uint8_t force;                 /* solve_blocking(force) in progress */
    uint8_t fz_on;                 /* 1: the judge uses the total-field model below */
    float fz_u0;                   /* mean raw z of the store at adoption */
    float fz_abc[3];               /* |h|^2 = a + b u + c u^2, u = z - fz_u0 (h corrected x, y) */
    uint32_t aged_adopts;          /* adoptions won by the ageing rule (cont_adopt.c) */
    float adopted_err;             /**< read-only: error estimate of the installed calibration, deg ("OK tolerance";
                                        NaN: none / from flash) */
    float adopted_tilt;            /* the tilt term in it (the solve's "Tilt in the estimate"), deg */
    /* judge (cont_judge.c, cont_flags.c): linear terms of the total-field model, transient judge state */
    float fz_hxy[4];               /* |h|^2 model terms hx, hy, hx^2 - hy^2, hx hy (unit radius) */
    float dist_e;                  /* smoothed relative residual */
    float dist_base;               /* its slow baseline (model bias) */
    float dist_var;                /* variance of (dist_e - dist_base) on clean samples */
    uint32_t dist_quiet_ms;        /* ms since the transient judge last exceeded its threshold */
    uint32_t dist_n;               /* samples since install that fed the transient judge */
    uint32_t fz_cover[2];          /* sectors of corrected heading the store covered at the fit */
    float fz_l[28];                /* Cholesky factor (packed lower) of the model's scaled normal matrix */
    float fz_s[7];                 /* feature scales of that matrix */
    uint32_t dist_flag_ms;         /* ms the transient judge has been above its threshold */
    float fz_u_prior[2];           /* u, u^2 terms of the last model that determined them */
    uint8_t fz_have_u;             /* 1: fz_u_prior holds them (the vertical field is kept by a change) */
    uint8_t fz_skip;               /* model form: u terms dropped (0: none, 1: u^2, 2: u and u^2) */
    uint8_t dist_flag;             /* 1: transient flagged (trust DISTURBED, not stored) */
    uint32_t snap_bin;             /* snapshot: next store bin to copy */
    uint32_t snap_n;               /* snapshot: samples copied */
    uint32_t snap_lv;              /* snapshot: of them level (the tilt term of the estimate) */
    uint32_t snap_stored;          /* store added + replaced at the snapshot */
    uint32_t drop_age;             /* cut: the oldest stored sample's age, in pushes (cont_step.c) */
    uint32_t drop_seq;             /* cut: samples older than this push count are dropped */
    uint32_t drop_changes;         /* changes declared when the cut was set (a change resets the
                                      store and its push counter: the cut is then void) */
    magcal_vec2_t drop_c;          /* the INCONSISTENT solve's ring (centre, radius): samples */
    float drop_r;                  /* off it by more than half the radius are dropped too */
    uint8_t drop_on;               /* cut of an INCONSISTENT solve (cont_adopt.c): 0 none, 1 pending
                                      (the next snapshot scans the ages), 2 set (it drops) */
    /* flags of the level-shift watch and the continuity gate (cont_shift.c, below) */
    uint8_t sh_far;                /* 1: the last position test was far */
    uint16_t sh_br_n;              /* non-positions since sh_prev, being bridged (cont_shift.c; 0: none) */
    uint8_t sh_cand_on;            /* 1: sh_cand is pending */
    uint8_t sh_lev;                /* 1: sh_prev was levelled by push_g's tilt compensation */
    uint8_t sh_have;               /* 0: no sh_prev; 1: sh_prev only; 2: and sh_last_n2 */
    uint8_t sh_open;               /* 1: an episode is open (a solve ending meanwhile is refused) */
    uint8_t sh_cut;                /* 1: a cut at sh_seq waits for the next snapshot */
    uint8_t sh_stale;              /* 1: the solve under way saw the store before a shift: refused */
    uint8_t cg_have;               /* 1: cg_prev valid */
    /* level-shift watch (cont_shift.c; drain side, while no calibration is installed) */
    magcal_vec2_t sh_prev;         /* the last drained sample (x, y), its stamp */
    uint32_t sh_prev_t;
    magcal_vec2_t sh_sum;          /* the open episode's jumps, summed */
    float sh_max_n2;               /* its largest jump, squared */
    uint32_t sh_jump_t;            /* stamp of its last jump */
    uint32_t sh_seq;               /* store push count at its first jump: the cut */
    uint32_t shifts;               /**< read-only: level shifts declared */
    uint32_t shift_refused;        /**< read-only: solves refused for a level shift */
    magcal_vec2_t sh_cand;         /* a candidate jump (confirmed by a small increment after it), */
    float sh_cand_n2;              /* its squared length, stamp and the store push count of its sample */
    uint32_t sh_cand_t;
    uint32_t sh_cand_seq;
    float sh_last_n2;              /* the last increment's squared length */
    float sh_inc2;                 /* the typical increment's (an average of squares), 0 = none yet */
    float sh_scale;                /* the distance scale (cont_shift.c), 0 = none yet */
    uint32_t sh_far_t;             /* stamp of the first of the far samples in a row */
    /* continuity gate (cont_shift.c; drain side) */
    magcal_vec2_t cg_prev;         /* the last drained sample, its stamp */
    uint32_t cg_prev_t;
    float cg_inc2;                 /* the typical increment (an average of clipped squares), 0 = none */
    magcal_vec2_t cg_keep;         /* the anchor: the last stored sample */
    uint32_t cg_keep_n;            /* samples since it (>= 1) */
    uint32_t cg_run;               /* refused samples in a row, each continuous with the one before */
    uint32_t cg_refused;           /**< read-only: samples the continuity gate kept out of the store */
    uint32_t worth_seen;           /* store added + replaced at the last coverage count (cont_step.c) */
    uint8_t worth_checked;         /* 1: worth_seen is valid */
    /* field-model fit at an adoption, time-sliced (cont_fzfit.c; the drain pauses meanwhile) */
    uint8_t fit_phase;             /* pass under way, 0 = none */
    uint8_t fit_skip;              /* model form being fitted (as fz_skip) */
    uint32_t fit_bin;              /* pass position: store bin */
    uint32_t fit_k;                /* pass position: sample in the bin */
    float fit_acc[3];              /* pass sums (z: sum, sum of squares, n; sums: n; sigma: ss, n) */
    float fit_b[7];                /* right-hand side of the normal equations, then the coefficients */
    float fit_a[28];               /* the full form's normal matrix (packed lower), its right-hand side */
    float fit_b0[7];
    uint32_t park_n;               /* ring samples parked in buf during the fit (cont_step.c) */
    uint32_t park_i;               /* parked samples drained since */
    magcal_vec3_t park_m;          /* the parked sample being drained, its stamp */
    uint32_t park_t;
    uint8_t fit_cal_ok;            /* cal valid (validated once at the fit's begin) */
    float fz_u_sd;                 /* RMS spread of the store's u at the fit (change judge, cont_judge.c) */
    /* slopes without gravity (cont_slope.c; continuous.h "Slopes without gravity") */
    float sl_acc[10];              /* the fit's level-z sums: 1 c s cc cs ss u uc us, then the refit's and
                                      the sigma pass's n */
    uint32_t sl_h[MAGCAL_CONT_SL_BINS]; /* the sigma pass's histogram of |residual| (cont_slope.c) */
    float sl_a[3];                 /* level raw z / raw radius against the corrected heading: a0 + a1 cos + a2 sin */
    float sl_vs;                   /* the store's robust mean square of raw z / raw radius about it (its slopes) */
    float sl_r;                    /* a judged sample's residual, smoothed over CONT_SL_SMOOTH_MS */
    float sl_v;                    /* its clipped absolute value's mean over CONT_SL_MS_MS (the slopes of now) */
    float sl_pk;                   /* the largest mean square, decaying over CONT_SL_PK_MS (the slopes of the roads) */
    float sl_rp;                   /* the largest sl_r^2, decaying over CONT_SL_RP_MS (the slope seen last) */
    uint32_t sl_life;              /* ms the online measures learnt since init (saturating) */
    uint32_t sl_tick;              /* ms since the slow measures last moved (CONT_SL_TICK_MS) */
    uint8_t sl_nk;                 /* drained samples mod 256 (the noise takes every 4th pair) */
    uint8_t sl_half;               /* 1: the online residual skips the next judged sample (every 2nd) */
    uint8_t sl_ok;                 /* CONT_SL_*: sl_a and sl_vs from the store's fit */
    uint8_t sl_on;                 /* 1: the current field-model fit measures them (no gravity ever) */
    uint8_t sl_zn;                 /* 1: sl_zp, sl_tp hold the sample before */
    float sl_zp;                   /* raw z of the drained sample before, its stamp */
    uint32_t sl_tp;
    float sl_nz;                   /* raw z's noise variance (raw units^2), from successive samples */
    float fz_miss;                 /* share of samples over the per-sample threshold, smoothed (cont_change.c) */
    uint8_t fz_unfit;              /* 1: the model does not explain the stream: its per-sample test does not flag */
    uint8_t cal_coarse;            /**< read-only: 1 = the installed calibration is coarse (hard
                                        iron only), 2 = an arc ellipse ("Arc calibration"); either
                                        way headings MAGCAL_TRUST_COARSE: do not store it as a full
                                        calibration */
    /* the coverage count of the sliced step, resumable over bins (cont_step.c, intake progress.c) */
    uint32_t cnt_words[MAGCAL_INTAKE_MASK_WORDS(MAGCAL_INTAKE_MAX_BINS)]; /* filled-bin mask so far */
    uint32_t cnt_bin;              /* next bin to count */
    uint32_t cnt_filled;           /* filled bins so far */
    uint32_t cnt_deep;             /* completion depth so far */
    uint8_t cnt_on;                /* 1: a count is under way */
    uint8_t cnt_gen;               /* store centre generation it started at */
    uint8_t cnt_src;               /* store centre source it started at */
    /* transient judge (cont_flags.c), issue 13's flags */
    uint32_t dist_age_ms;          /* ms of stamps since the transient judge was reset (baseline warm-up) */
    /* tilt compensation of push_g (cont_life.c; written by push only) */
    float tc_tan2;                 /* tan^2(cfg.tilt_comp_deg), set at init (0 = off) */
    float tc_k;                    /* raw shift per unit of tilt (the vertical field, raw units); valid when tc_ok */
    float tc_kl;                   /* the k samples are levelled with: tc_k, held while a calibration
                                      fitted on (or levelled to) levelled samples is in force */
    float tc_s[4];                 /* its within-sector regression sums: q q, d q, d d, z q (co-variations) */
    float tc_rho;                  /* -(z q) / (R q q): the share of q that raw z confirms as tilt */
    uint32_t tc_n;                 /* samples in the sums (beyond each sector's first) */
    float tc_mq[MAGCAL_CONT_TC_BINS]; /* per heading sector (from the store's centre): mean q (tilt along the
                                         radial direction) of the samples it took */
    float tc_md[MAGCAL_CONT_TC_BINS]; /* their mean distance from the centre */
    float tc_mz[MAGCAL_CONT_TC_BINS]; /* their mean raw z */
    float tc_lt[MAGCAL_CONT_TC_BINS][2]; /* the tilt (x, y) of its last sample taken */
    uint16_t tc_nb[MAGCAL_CONT_TC_BINS]; /* samples it took (0: none since its means were dropped) */
    uint32_t tc_changes;           /* cc->changes the sectors' means belong to */
    uint8_t tc_gen;                /* and the store's centre generation */
    volatile uint8_t tc_ok;        /* 1: tc_k is estimated well enough to level samples */
    uint8_t tc_rst;                /* 1: tc_k restored (magcal_cont_restore_tilt) and in force until the
                                      regression is determined */
    uint8_t tc_acc;                /* 1: k is determined but raw z does not confirm the tilt (rho < 0.5):
                                      the accelerometer's tilt is mostly acceleration */
    volatile uint8_t tc_on;        /* 1: samples are levelled (latched once tc_ok while no calibration is
                                      installed or a relearn is under way: the judge's field model and
                                      the stream it judges then agree) */
    volatile uint32_t tc_levelled; /* samples levelled (pushed as LEVEL after the compensation) */
    magcal_vec3_t tc_m;            /* the levelled sample being queued (here, not on push's stack) */
    magcal_vec3_t tc_t;            /* and its tilt (z = 1: known) */
    magcal_vec3_t tc_h;            /* the tilt known 1..2 s before the last one (z = 0.5; 0: none yet) */
    float tc_hp[2];                /* the snapshot it takes next */
    uint32_t tc_h_ms;              /* the push stamp of that snapshot */
    float st_tx;                   /* the mean tilt of the samples the drain stored (levelled ones count */
    float st_ty;                   /* as level; unknown tilts are left out): EMA over CONT_TF_N samples */
    float st_t2;                   /* and of the squared tilt (its spread) */
    uint32_t st_tn;                /* samples in that mean (saturates) */
    float cal_tx;                  /* the installed calibration's: that mean when it was adopted (the tilt */
    float cal_ty;                  /* its unlevelled fit saw; its centre is off by k times it) */
    float cal_ts;                  /* the spread (RMS about the mean) of that tilt */
    uint32_t levels;               /* unlevelled calibrations levelled by their fit's tilt (cont_step.c) */
    uint32_t relevels;             /* relevels started */
    uint8_t cal_tk;                /* 1: cal_tx, cal_ty known (adopted here with enough known tilts) */
    uint8_t cal_conv;              /* 1: during a relevel, the heading levels its sample and moves it
                                      by k t_cal (the unlevelled fit's centre: one slope) */
    uint8_t cal_lv;                /* 1: the installed calibration was fitted on levelled samples (or
                                      confirmed on them): the heading and the judge level their sample */
    uint8_t relevel;               /* 1: the compensation came on under an unlevelled calibration: the
                                      store refills with levelled samples while the judge un-levels */
    magcal_vec3_t jm;              /* the drained sample as the judge sees it (un-levelled: relevel) */
    /* the transient judge's bias regression (cont_flags.c): the stream's heading-dependent bias
     * of the residual and of raw z, learnt on clean samples */
    float dist_ue;                 /* smoothed raw z / R (the vertical channel) */
    float dist_ub;                 /* its baseline */
    float dist_uvar;               /* variance of the vertical channel's unexplained part, clean samples */
    float dist_fe[4];              /* smoothed regressors: cos, sin, cos 2, sin 2 of the corrected heading */
    float dist_fb[4];              /* their baselines */
    float dist_fo[4];              /* and their values when the flag rose (held while it is up) */
    float dist_mx[10];             /* moments of the regressors' deviations (packed lower) */
    float dist_mr[4];              /* their moments with the residual's deviation */
    float dist_mu[4];              /* their moments with the vertical channel's deviation */
    float dist_th[8];              /* coefficients: residual 0..3, vertical 4..7 */
    float dist_pm[18];             /* learning held back at a move's onset (cont_flags.c): the moments'
                                      weighted sums (10 regressors', 4 residual's, 4 vertical's) */
    float dist_pw;                 /* their sum of weights */
    uint32_t dist_still_ms;        /* ms of judged samples the heading has not moved from its baseline */
    uint32_t dist_on_ms;           /* ms since a move's onset after a still heading (0: none held back) */
    float dist_ur;                 /* raw radius the vertical channel's state is scaled by (cont_flags.c) */
    uint32_t dist_dt;              /* ms between the last two samples the transient judge took (its peek's step) */
    /* offset-only relearn (src/adopt/calibrator_offset.c): a circle fit on the snapshot, in the
     * frame of the installed calibration (u = M (m - offset) / radius) */
    uint8_t off_mode;              /* 1: the solve under way (or starting) is the offset-only fit */
    uint8_t off_pass;              /* its pass: 1 fit, 2 residual RMS, 3 refit, 4 residual model, 5 end */
    uint8_t cal_offset;            /**< read-only: 1 = the installed calibration is an offset-only
                                        relearn (the previous soft iron, a refitted hard iron) */
    uint32_t off_i;                /* position in the snapshot */
    uint32_t off_block;            /* cc->changes + 1 after a SHAPE_CHANGED verdict: no offset fit
                                      until the next change (0: none) */
    uint32_t off_n;                /* samples in the pass sums */
    float off_cov;                 /* live coverage that started the fit */
    float off_a[25];               /* normal matrix (5 x 5 row-major; the circle's 3 x 3 in passes 1, 3) */
    float off_b[5];                /* right-hand side */
    float off_c[3];                /* circle: centre x, y, radius (unit frame) */
    float off_ss;                  /* sum of squared residuals */
    float off_thr;                 /* residual gate (unit frame) */
    float off_lam;                 /* end: largest eigenvalue of the centre's covariance */
    float off_s3;                  /* end: residual sigma of the 3-parameter circle */
    float off_sr;                  /* end: the radius's standard error */
    /* gyro heading check ("Gyro heading check"): push_imu writes gy_* and ring_dy, the drain rj_* */
    float ring_dy[MAGCAL_CONT_RING]; /* rotation about the up axis since the sample queued before, deg
                                      (NaN: unknown, a sample without a rate) */
    float gy_acc;                  /* push_imu: rotation accumulated since the last sample queued, deg */
    float gy_w;                    /* its last rate about the up axis, deg/s */
    uint32_t gy_t;                 /* and its stamp */
    uint8_t gy_on;                 /* 1: gy_w, gy_t valid */
    uint8_t gy_pend;               /* 1: the sample being queued is push_imu's */
    int8_t rj_sgn;                 /* heading move per gyro rotation about up: -1 (init), +1 (mirrored) */
    uint8_t rj_on;                 /* 1: the track runs */
    uint8_t rj_flag;               /* 1: the magnetic heading left the gyro's track (DISTURBED) */
    uint8_t ga_on;                 /* gyro-aided gravity ("Gyro-aided gravity", below): 1 started */
    uint8_t ga_lock;               /* 1: locked (its gravity replaces the accelerometer's) */
    uint8_t ga_quiet;              /* 1: locked and the accelerometer within 0.3 deg of it (k may learn) */
    float rj_psi;                  /* the track, deg */
    float rj_prev;                 /* the last judged magnetic heading, deg */
    float rj_b;                    /* the gyro's bias about the up axis, deg/s (the loop's integral) */
    float rj_var;                  /* the deviation's mean square on clean samples, deg^2 */
    float rj_dev;                  /* the last deviation, deg */
    float rj_rot;                  /* the recent rotation (|rotation| decaying at the loop's rate), deg */
    float rj_sx;                   /* sign evidence: sums of (heading move x rotation), */
    float rj_sa;                   /* rotation^2 */
    float rj_turn;                 /* and |rotation|, deg */
    uint32_t rj_t;                 /* stamp of the last judged sample */
    uint32_t rj_ms;                /* ms judged (the warm-up; again after a sign turn) */
    uint32_t rj_coast_ms;          /* ms the track has coasted */
    uint32_t rj_flags;             /* flags raised */
    /* gyro-aided gravity ("Gyro-aided gravity"): push_imu writes ga_* */
    magcal_vec3_t ga_u;            /* the up direction (unit, body axes) */
    magcal_vec3_t ga_b;            /* the gyro's bias, rad/s (the filter's integral) */
    magcal_vec3_t ga_as;           /* the smoothed accelerometer */
    magcal_vec3_t ga_g;            /* the gravity push_g takes from it (g's units) */
    float ga_lvl;                  /* the running level of its magnitude */
    float ga_tl;                   /* s of consistent pulls towards the lock */
    float ga_tr;                   /* s of pulls rejected while locked */
    uint32_t ga_t;                 /* the last stamp */
    uint32_t ga_unlocks;           /* locks lost */
    uint16_t ga_nl;                /* samples in the level (its mean until the average's weight) */
} magcal_cont_t;

/**
 * @brief Initialise on caller storage.
 * @param[out] cc      instance.
 * @param[in]  cfg     configuration (copied); cfg->intake.dims must be 2.
 * @param[in]  installed optional (NULL): calibration restored from flash (validated; its centre
 *                     then indexes the store; generation stays 0).
 * @param[in]  slots   store slots, n_slots >= MAGCAL_CONT_SLOTS(intake.bins, intake.per_bin),
 *                     16..MAGCAL_MAX_SAMPLES.
 * @param[in]  buf     solver buffer of n_slots samples.
 * @param[in]  work    solver workspace, 4-aligned, >= MAGCAL_CALIBRATOR_WORKSPACE_LEN(n_slots).
 * @param[in]  work_len its bytes.
 * @return MAGCAL_OK, MAGCAL_ERR_NULL, MAGCAL_ERR_ARG (a cfg value out of range, dims != 2),
 *         MAGCAL_ERR_NONFINITE, MAGCAL_ERR_WORKSPACE, MAGCAL_ERR_ALIGNMENT, any status of
 *         magcal_cal2d_validate() for `installed`.
 */
magcal_status_t magcal_cont_init(magcal_cont_t *cc, const magcal_cont_cfg_t *cfg,
                                 const magcal_cal2d_t *installed, magcal_intake_slot_t *slots,
                                 size_t n_slots, magcal_vec2_t *buf, void *work, size_t work_len);

/**
 * @brief Offer one raw sample (x right, y forward, z up; sensor unit) with its time in ms
 *        (wrapping uint32 allowed). ISR-safe (file comment). O(1).
 * @return MAGCAL_OK (queued), MAGCAL_ERR_BUFFER_FULL (ring full: dropped, counted),
 *         MAGCAL_ERR_NULL, MAGCAL_ERR_NOT_INITIALISED.
 */
magcal_status_t magcal_cont_push(magcal_cont_t *cc, const magcal_vec3_t *m, uint32_t t_ms);

/**
 * @brief As magcal_cont_push, with the accelerometer's gravity at the same instant: the sample
 *        is classified LEVEL or TILTED for the store's level preference (intake.h: a level
 *        sample replaces a pitched one of its bin first, a pitched one never replaces a level
 *        one, pitched samples are taken while a bin is short of level ones, so a drive that is
 *        hilly throughout still calibrates). ISR-safe as magcal_cont_push (the classifier's state
 *        is written by push only). O(1), no trigonometry: g is smoothed (exponential average,
 *        time constant MAGCAL_CONT_G_SMOOTH_MS of the push stamps: vibration, sensor noise), and
 *        the sample is LEVEL when the smoothed g has
 *        g_x^2 + g_y^2 <= tan^2(cfg.intake.tilt_limit_deg) g_z^2 (tan^2 precomputed at init)
 *        and | |g|^2 - L | <= cfg.intake.g_band_rel L, L the running level of |g|^2 (an
 *        exponential average of time constant MAGCAL_CONT_G_TAU_MS, seeded by the first
 *        sample): hard braking, acceleration and bumps are not level. g in any unit
 *        (the tests are ratios), body axes as m (x right, y forward, z up; the sign of g_z does
 *        not matter). A car's accelerometer also sees the centripetal acceleration in a turn:
 *        those samples read as tilted (they are still stored while their bin is short of level
 *        ones). g NULL, a non-finite g, |g| = 0 or tilt_limit_deg 0: the sample is pushed
 *        without a tilt code, exactly as magcal_cont_push.
 *        docs/calibrator.md "Level samples from the accelerometer". Tilt compensation (file
        comment "Tilt compensation"): once the vertical field is learnt, a steady sample pitched
        within cfg.tilt_comp_deg is levelled before it is queued, and queued LEVEL.
 * @param[in,out] cc   initialised instance.
 * @param[in]     m    raw magnetometer sample.
 * @param[in]     g    specific force (accelerometer), or NULL.
 * @param[in]     t_ms time stamp, ms (wrapping).
 * @return as magcal_cont_push.
 */
magcal_status_t magcal_cont_push_g(magcal_cont_t *cc, const magcal_vec3_t *m, const magcal_vec3_t *g,
                                   uint32_t t_ms);

/**
 * @brief As magcal_cont_push_g, with the gyro's rates at the same instant for the gyro heading
 *        check ("Gyro heading check"). ISR-safe as magcal_cont_push (its rate state is written by
 *        push only). O(1).
 * @param[in,out] cc   initialised instance.
 * @param[in]     m    raw magnetometer sample.
 * @param[in]     g    specific force (accelerometer), or NULL (then the rate about body z counts).
 * @param[in]     w    angular rate, rad/s, body axes as m (a mirrored frame is found on the
 *                     turns), or NULL / non-finite: pushed as magcal_cont_push_g.
 * @param[in]     t_ms time stamp, ms (wrapping).
 * @return as magcal_cont_push.
 */
magcal_status_t magcal_cont_push_imu(magcal_cont_t *cc, const magcal_vec3_t *m, const magcal_vec3_t *g,
                                     const magcal_vec3_t *w, uint32_t t_ms);

/**
 * @brief The tilt compensation's state to keep with the calibration across a power cycle
 *        (record.h tilt_k, tilt_levelled): *k = the vertical field the samples are levelled
 *        with while it is valid (else 0), *levelled = 1 when the installed calibration was
 *        fitted on (or confirmed on) levelled samples. Task context.
 * @return MAGCAL_OK; MAGCAL_ERR_NULL; MAGCAL_ERR_NOT_INITIALISED.
 */
magcal_status_t magcal_cont_tilt_state(const magcal_cont_t *cc, float *k, uint8_t *levelled);

/**
 * @brief Restore the tilt compensation kept with the installed calibration (after
 *        magcal_cont_init with that calibration, before the first push): samples are levelled
 *        with k from the first push_g on, and the installed calibration counts as levelled when
 *        `levelled` is 1 (its heading and judge level their sample; no relevel), so a vehicle
 *        that powers up on a hill does not read the hill as a change. k stays in force until the
 *        stream's own regression is determined (then that decides, as without a restore).
 *        Task context, before any push.
 * @param[in,out] cc       initialised instance with a calibration installed.
 * @param[in]     k        vertical field in raw units, 0 < |k| <= 3 x the calibration's raw radius.
 * @param[in]     levelled 0 or 1.
 * @return MAGCAL_OK; MAGCAL_ERR_NULL; MAGCAL_ERR_NOT_INITIALISED; MAGCAL_ERR_STATE (no
 *         calibration installed, or tilt compensation off: cfg.tilt_comp_deg 0);
 *         MAGCAL_ERR_NONFINITE; MAGCAL_ERR_ARG (k out of range, levelled > 1).
 */
magcal_status_t magcal_cont_restore_tilt(magcal_cont_t *cc, float k, uint8_t levelled);

/** @brief One bounded unit of work (file comment); MAGCAL_CONT_IDLE for NULL / uninitialised. */
magcal_cont_outcome_t magcal_cont_step(magcal_cont_t *cc);

/**
 * @brief Host / test convenience: drain the ring, then, if a solve is worth running (or force),
 *        run it to its end. @return the final outcome (MAGCAL_CONT_IDLE when no solve ran).
 */
magcal_cont_outcome_t magcal_cont_solve_blocking(magcal_cont_t *cc, int force);

/**
 * @brief Heading of a raw sample (x, y give the heading; z feeds the total-field judge) with the
 *        installed calibration and its trust (the judge of step(), no state change). Task context.
 *        Trust, first that applies: UNCALIBRATED (nothing installed); CHANGED (relearning);
 *        DISTURBED (the sample mismatches the calibration, a transient or the gyro's check flags
 *        it, an open change episode is wide or holds MAGCAL_CONT_EPISODE_TRUST_MS of mismatch,
 *        or an axis is at cfg.intake.range_limit); TILTED ("Tilt in the trust"); COARSE (a coarse
 *        or arc calibration, or one whose estimate is above cfg.ok_max_err_deg: "OK
 *        tolerance"; or the first second after an install or a field-model fit, while the
 *        transient judge's baselines settle and it can raise no flag); else OK.
 * @return MAGCAL_OK, MAGCAL_ERR_NULL, MAGCAL_ERR_NOT_INITIALISED, MAGCAL_ERR_NONFINITE,
 *         MAGCAL_ERR_ZERO_FIELD (as magcal_heading_compute()).
 */
magcal_status_t magcal_cont_heading(const magcal_cont_t *cc, const magcal_vec3_t *m, float declination_deg,
                                    magcal_cont_heading_t *out);

/** @brief Live progress. @return MAGCAL_OK, MAGCAL_ERR_NULL, MAGCAL_ERR_NOT_INITIALISED. */
magcal_status_t magcal_cont_progress(const magcal_cont_t *cc, magcal_cont_progress_t *out);

/** @brief Status of the last finished solve (MAGCAL_OK before any). */
magcal_status_t magcal_cont_status(const magcal_cont_t *cc);


#ifdef __cplusplus
}
#endif

#endif /* MAGCAL_CONTINUOUS_H */
