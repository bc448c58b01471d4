/*
 * Internal interface of the continuous calibrator (src/loop/): lifecycle and push (cont_life.c),
 * step and sliced solve (cont_step.c), adoption over time (cont_adopt.c), per-sample judge and
 * change detection (cont_judge.c per-sample judge, cont_change.c episodes and change decision,
 * cont_flags.c transient flags, cont_fzfit.c the judge's field-model fit; their shared internals in
 * cont_judge_internal.h). Not installed. docs/calibrator.md "Continuous calibrator".
 */
#ifndef MAGCAL_CONT_INTERNAL_H
#define MAGCAL_CONT_INTERNAL_H

#include "../adopt/calibrator_internal.h"
#include "magcal/continuous.h"

#define MAGCAL_CONT_MAGIC 0x434F4E54u /* "CONT" */
#define MAGCAL_CONT_SECTORS 36u       /* change-detection sectors of the corrected heading */
#define MAGCAL_CONT_MAX_DT_MS 1000u   /* a gap in the stamps counts at most this much */
#define MAGCAL_CONT_TILT_LEVELLED 3u  /* ring tilt code: LEVEL after push_g's tilt compensation (the
                                         level-shift watch does not take the switch as a jump) */
#define CONT_TF_N 256u    /* the store's mean tilt (cont_step.c): an EMA over this many stored samples */
#define CONT_TF_MIN 64u   /* an adopted calibration's fit tilt is known from this many known tilts */
#define CONT_TF_SPREAD 0.02f /* and is levelled by it when their spread is within this (1.1 deg): on
                                one slope the fit's only error is the shift; a spread of tilts bent
                                the ellipse too (tests/test_cont_drive.c, circles over hills: the
                                shifted calibration read levelled samples 6.5 % inside its radius) */

/* Verdict of one sample under the installed calibration. */
typedef struct {
    float rel;      /* |h| / R - 1 (NaN without a calibration) */
    float heading;  /* corrected heading, deg */
    uint8_t sector; /* 0..35 */
    uint8_t mismatch; /* 1: |rel| above the threshold */
    float unc;      /* model's prediction variance at this sample / its noise variance (0: none) */
    uint8_t gross;  /* 1: evidence of a change (beyond the change threshold, or z out of reach of pitch) */
    uint8_t over;   /* 1: |rel| above the per-sample threshold (whether or not it flags, cc->fz_unfit) */
    uint8_t tilted; /* 1: judged unlevelled beyond the level limit by the radius alone (no field
                       model): neither evidence of a change nor of consistency (cont_change.c) */
    float u;        /* raw z / the installed raw radius (the transient judge's vertical channel) */
    float cs[2];    /* cos, sin of the corrected heading (its bias regressors) */
} magcal_cont_judge_t;

int magcal_cont_ok(const magcal_cont_t *cc);
/* Weight of an exponential average with time constant tau_ms for a step of dt_ms (dt counted at
 * most tau_ms): dt / (dt + tau) (cont_life.c). */
float magcal_cont_ema_w(uint32_t dt_ms, uint32_t tau_ms);
/* One step of an exponential average of a vector: s += (x - s) w. */
static inline void magcal_cont_ema3(magcal_vec3_t *s, const magcal_vec3_t *x, float w)
{
    s->x += (x->x - s->x) * w;
    s->y += (x->y - s->y) * w;
    s->z += (x->z - s->z) * w;
}
/* Judge raw (x, y) under cc->cal: 0 when no calibration is installed (j->mismatch 0). `radius`
 * 1: by |h| / R - 1 even when the field model is on (a levelled sample under a calibration fitted
 * on unlevelled ones, whose model's u terms are the hills': cal_conv). */
int magcal_cont_judge(const magcal_cont_t *cc, const magcal_vec3_t *m, int radius, magcal_cont_judge_t *j);
/* Fit the judge's total-field model and noise on the store under cc->cal (at an adoption),
 * time-sliced: begin (O(1): the judge is radius-only, fz_on 0, until the fit ends), then steps
 * within budget b (at least one visit each; the store must not change meanwhile: the drain
 * pauses, cont_step.c) until a step returns 1 (the model and cal_sigma_rel set, fz_on 1, or the
 * fit failed and fz_on stays 0). Budget unlimited: the whole fit in one step. */
void magcal_cont_fit_begin(magcal_cont_t *cc);
int magcal_cont_fit_step(magcal_cont_t *cc, magcal_cal_budget_t *b);
/* Episode update with one judged sample at t_ms; returns 1 when a change is declared now. */
int magcal_cont_episode(magcal_cont_t *cc, const magcal_cont_judge_t *j, uint32_t t_ms);
/* Reset the transient-disturbance judge (cont_flags.c) after a new calibration or model. */
void magcal_cont_transient_reset(magcal_cont_t *cc);
/* Gyro heading check (cont_rate.c, continuous.h "Gyro heading check"): one judged sample j at
 * t_ms with the gyro's rotation dy (deg, NaN: none) since the sample before; sets cc->rj_flag.
 * The reset restarts the track (a new calibration, a sample not judged). */
void magcal_cont_rate(magcal_cont_t *cc, const magcal_cont_judge_t *j, float dy, uint32_t t_ms);
void magcal_cont_rate_reset(magcal_cont_t *cc);
/* Gyro-aided gravity (cont_grav.c, continuous.h "Gyro-aided gravity"): one accelerometer sample g
 * (NULL: none) and rate w (rad/s, finite) at t_ms; the gravity push_g takes: the locked estimate
 * (&cc->ga_g, g's units) where the accelerometer reads more than gravity, else g. */
const magcal_vec3_t *magcal_cont_grav(magcal_cont_t *cc, const magcal_vec3_t *g, const magcal_vec3_t *w,
                                      uint32_t t_ms);
/* 1 while no gravity ever came (push alone: no tilt was ever known, cc->tc_t): the slopes are
 * then measured from raw z (cont_slope.c). */
static inline int magcal_cont_no_gravity(const magcal_cont_t *cc)
{
    return (cc->tc_t.z > 0.0f) ? 0 : 1;
}
/* Slopes without gravity (cont_slope.c): the store's level raw z in the field-model fit (its z
 * pass: add each ring sample, then solve; its sigma pass: the refit's sums, then refit (1: a
 * slope pass follows); the slope pass: the histogram of each, then end), the online measures of
 * each judged sample's residual (not a transient's, not change evidence), and the heading error
 * the slopes cause at k_r = k / R (degrees; INFINITY while they are unmeasured). */
#define CONT_SL_NONE 0u   /* sl_ok: nothing fitted */
#define CONT_SL_SOLVED 1u /* the level fitted, its residual being summed */
#define CONT_SL_DONE 2u   /* the store's slopes measured */
#define CONT_SL_ACC 10u   /* sums of the fit's passes */
void magcal_cont_slope_add(magcal_cont_t *cc, const magcal_vec2_t *h, float z);
void magcal_cont_slope_solve(magcal_cont_t *cc);
void magcal_cont_slope_res(magcal_cont_t *cc, const magcal_vec2_t *h, float z);
int magcal_cont_slope_refit(magcal_cont_t *cc);
void magcal_cont_slope_hist(magcal_cont_t *cc, const magcal_vec2_t *h, float z);
void magcal_cont_slope_end(magcal_cont_t *cc);
void magcal_cont_slope(magcal_cont_t *cc, const magcal_cont_judge_t *j, uint32_t dt);
/* Raw z's noise from successive drained samples (also before a calibration; the caller skips it
 * while a solve runs; every 4th pair counts). */
void magcal_cont_slope_noise(magcal_cont_t *cc, const magcal_vec3_t *m, uint32_t t_ms);
float magcal_cont_slope_err_deg(const magcal_cont_t *cc, float k_r);
/* Declare a change: drop the store, relearn. */
void magcal_cont_declare_change(magcal_cont_t *cc);
/* 1 when an open episode spans at least cfg.change_bins sectors (every heading suspect). */
int magcal_cont_episode_wide(const magcal_cont_t *cc);
/* Finish a solve: the batch verdict `st` with cc->last, ageing rule, install. Returns the outcome. */
magcal_cont_outcome_t magcal_cont_finish_solve(magcal_cont_t *cc, magcal_status_t verdict);
/* Index the store around the installed calibration (its centre, raw radius; none when that is 0). */
void magcal_cont_centre_store(magcal_cont_t *cc);
/* Install calibration c (raw radius r_raw, relative noise sigma) and index the store around it. */
void magcal_cont_install(magcal_cont_t *cc, const magcal_cal2d_t *c, float r_raw, float sigma);
/* Level-shift watch (cont_shift.c, continuous.h "Level shift"): watch one drained sample at t_ms
 * (the drain, before its judge; levelled: push_g's tilt compensation moved it); clear the watch (init, reset, install); 1 when a solve ending now
 * must be refused (a shift declared after its snapshot, or an episode open); at a snapshot's
 * start, a pending shift becomes the snapshot's cut (drop_on 2 at the episode's first jump). */
void magcal_cont_shift_watch(magcal_cont_t *cc, const magcal_vec3_t *m, uint32_t t_ms, int levelled);
void magcal_cont_shift_clear(magcal_cont_t *cc);
int magcal_cont_shift_refuses(const magcal_cont_t *cc);
void magcal_cont_shift_to_cut(magcal_cont_t *cc);
/* Continuity gate (cont_shift.c, continuous.h "Continuity gate"): 1 when the drained sample m at
 * t_ms may be stored (always once a calibration judges the stream, outside a relearn). */
int magcal_cont_continuity(magcal_cont_t *cc, const magcal_vec3_t *m, uint32_t t_ms);
/* Coarse stage (cont_adopt.c): hand the solver its coarse mode for the installed calibration
 * (cc->has_cal, cc->cal_coarse); the live coverage that starts a solve. */
void magcal_cont_coarse_mode(magcal_cont_t *cc);
float magcal_cont_solve_cov(const magcal_cont_t *cc);
/* Arc stage settings of cfg (cont_adopt.c): MAGCAL_OK, MAGCAL_ERR_NONFINITE or MAGCAL_ERR_ARG. */
magcal_status_t magcal_cont_arc_cfg_check(const magcal_cont_cfg_t *c);
/* Offset-only relearn (src/adopt/calibrator_offset.c, docs/calibrator.md "Offset-only relearn"). */
/* 1 when a relearn may fit the offset only: RELEARNING, a full calibration installed, the stage on
 * (cfg.offset_coverage_deg > 0) and no SHAPE_CHANGED verdict since the last change. */
int magcal_cont_offset_eligible(const magcal_cont_t *cc);
/* Whether the live coverage starts a solve (1) and which: cc->off_mode 0 the full solve (coverage_deg
 * >= full, the full solve's start, magcal_cont_solve_cov), 1 the offset-only fit (eligible,
 * coverage_deg >= cfg.offset_coverage_deg). src/adopt/ calls nothing of src/loop/ (the target
 * cross-check's host twin links src/adopt/ without it). */
int magcal_cont_offset_pick(magcal_cont_t *cc, float coverage_deg, float full);
/* Start the fit on the snapshot cc->buf[0 .. cc->snap_n) (O(1)). */
void magcal_cont_offset_begin(magcal_cont_t *cc);
/* Fit work within `budget` estimated M4F instructions (UINT32_MAX: to its end), at least one
 * visit: MAGCAL_IN_PROGRESS, or the verdict (cc->last filled; MAGCAL_OK: cc->cand is the new
 * calibration, report radius / est_* as the solver's). */
magcal_status_t magcal_cont_offset_step(magcal_cont_t *cc, uint32_t budget);

#endif /* MAGCAL_CONT_INTERNAL_H */
