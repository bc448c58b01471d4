/*
 * Continuous calibrator, adoption over time. A finished solve has the batch verdict (the gates and
 * the never-worse rule of calibrator.h, applied to the calibration installed when the solve
 * started). Ageing (as NXP ages its fit error with time): the installed calibration's confidence
 * decays with the time t since its adoption (ms of the push stamps; gaps count at most 1 s).
 * The margin by which the new calibration must be better falls from
 * MAGCAL_CALIBRATOR_ADOPT_MARGIN towards 1:
 *     margin(t) = 1 + (MAGCAL_CALIBRATOR_ADOPT_MARGIN - 1) / (1 + t / cfg.age_ms)
 * and a NOT_BETTER verdict is overturned when current_err_deg > margin(t) x est_param_err_deg:
 * the installed calibration's error measured on the new data exceeds the new one's own estimate,
 * so a genuinely better calibration wins eventually, and never one estimated worse (margin >= 1).
 * Coarse stage (continuous.h "Coarse calibration"): while no calibration is installed, the solver
 * may fit the hard-iron circle on an arc (calibrator.h "Coarse stage") and a solve starts at
 * cfg.coarse_coverage_deg; once any calibration is installed, never again (a coarse one is
 * replaced by a full ellipse with margin 1, calibrator_judge.c magcal_ph_harm_c).
 * Arc stage (continuous.h "Arc calibration", opt-in): likewise while no calibration is installed,
 * a solve starts at cfg.arc_coverage_deg and the solver may install an ellipse fitted on an arc
 * (calibrator.h "Arc stage"), marked cc->cal_coarse = 2 (headings MAGCAL_TRUST_COARSE).
 * A store of two installations (the solver's consistency gate, MAGCAL_ERR_INCONSISTENT): a cut at
 * half the oldest stored sample's age, applied by the next snapshot (cont_step.c), which starts at
 * once (docs/calibrator.md "Consistency gate").
 */
#include <math.h>

#include "cont_internal.h"
#include "magcal_internal.h"

void magcal_cont_coarse_mode(magcal_cont_t *cc)
{
    /* before the first calibration only: a coarse one is replaced by a full ellipse (>= 270 deg),
     * not by another circle (fewer, later solves: the loop after it runs as without the stage) */
    float co = 0.0f;
    float arc = 0.0f;
    if (cc->has_cal == 0u) {
        co = cc->cfg.coarse_coverage_deg;
        arc = cc->cfg.arc_coverage_deg;
    }
    magcal_calibrator_set_coarse(&cc->solver, co, cc->cfg.coarse_max_err_deg, cc->cal_coarse);
    magcal_calibrator_set_arc(&cc->solver, arc, cc->cfg.arc_max_err_deg, cc->cfg.arc_model_deg);
}

magcal_status_t magcal_cont_arc_cfg_check(const magcal_cont_cfg_t *c)
{
    if (!magcal_isfinite_f(c->arc_coverage_deg) || !magcal_isfinite_f(c->arc_max_err_deg) ||
        !magcal_isfinite_f(c->arc_model_deg)) {
        return MAGCAL_ERR_NONFINITE;
    }
    if (c->arc_coverage_deg < 0.0f || c->arc_coverage_deg > c->solve_coverage_deg ||
        !(c->arc_max_err_deg > 0.0f) || c->arc_model_deg < 0.0f) {
        return MAGCAL_ERR_ARG;
    }
    return MAGCAL_OK;
}

float magcal_cont_solve_cov(const magcal_cont_t *cc)
{
    float cov = cc->cfg.solve_coverage_deg;
    const float co = cc->solver.coarse_min_cov;
    const float arc = cc->solver.arc_min_cov;
    if (co > 0.0f && co < cov) {
        cov = co;
    }
    if (arc > 0.0f && arc < cov) {
        cov = arc;
    }
    return cov;
}

void magcal_cont_centre_store(magcal_cont_t *cc)
{
    magcal_vec3_t centre;
    centre.x = cc->cal.offset.x;
    centre.y = cc->cal.offset.y;
    centre.z = 0.0f;
    if (cc->cal_raw_radius > 0.0f) {
        (void)magcal_intake_set_centre(&cc->store, &centre, cc->cal_raw_radius);
    }
}

void magcal_cont_install(magcal_cont_t *cc, const magcal_cal2d_t *c, float r_raw, float sigma)
{
    cc->cal = *c;
    cc->has_cal = 1u;
    cc->cal_raw_radius = r_raw;
    cc->cal_sigma_rel = magcal_isfinite_f(sigma) && sigma > 0.0f ? sigma : 0.0f;
    magcal_cont_centre_store(cc);
    cc->fz_on = 0u;
    cc->episode_open = 0u;
    cc->mis_ms = 0u;
    cc->clean_ms = 0u;
    cc->mis_bins[0] = 0u;
    cc->mis_bins[1] = 0u;
    magcal_cont_transient_reset(cc);
    magcal_cont_rate_reset(cc); /* the heading jumps with the calibration: the gyro's track restarts */
    magcal_cont_shift_clear(cc);
    magcal_cont_coarse_mode(cc);
}

static float cont_margin(const magcal_cont_t *cc)
{
    return 1.0f + (MAGCAL_CALIBRATOR_ADOPT_MARGIN - 1.0f) / (1.0f + (float)cc->age_ms_acc / cc->cfg.age_ms);
}

magcal_cont_outcome_t magcal_cont_finish_solve(magcal_cont_t *cc, magcal_status_t verdict)
{
    magcal_status_t st = verdict;
    magcal_cal_report_t *r = &cc->last;
    cc->solves++;
    cc->stored_at_solve = (cc->store.ctr.added + cc->store.ctr.replaced);
    cc->solve_ms_acc = 0u;
    /* (a circle or an arc never overturns the verdict against a full calibration: not even by ageing) */
    if (st == MAGCAL_ERR_NOT_BETTER && cc->has_cal != 0u && ((r->coarse == 0u && r->arc == 0u) || cc->cal_coarse != 0u) &&
        magcal_isfinite_f(r->current_err_deg) &&
        magcal_isfinite_f(r->est_param_err_deg) &&
        r->current_err_deg > fmaxf(cont_margin(cc) * r->est_param_err_deg, MAGCAL_CALIBRATOR_ADOPT_MIN_DEG)) {
        cc->cand = r->cal;
        r->adopted = 1u;
        r->adopt_rule = MAGCAL_ADOPT_BETTER;
        r->status = MAGCAL_OK;
        st = MAGCAL_OK;
        cc->aged_adopts++;
    }
    if (st == MAGCAL_OK && magcal_cont_shift_refuses(cc) != 0) {
        /* a level shift after the snapshot, or one under watch (cont_shift.c): the samples may be
         * of two installations, or of the one just left; the calibration in force is untouched and
         * the shift's own cut (not the consistency gate's) rebuilds the store */
        r->adopted = 0u;
        r->status = MAGCAL_ERR_INCONSISTENT;
        cc->last_status = MAGCAL_ERR_INCONSISTENT;
        cc->shift_refused++;
        return MAGCAL_CONT_FAILED;
    }
    cc->last_status = st;
    if (st == MAGCAL_OK) {
        /* an episode open at the solve's end is evidence gathered after its snapshot (a change
         * under way while the solve ran on the store before it): it survives the install, and
         * samples consistent with the new calibration close it after cfg.clear_ms as usual */
        const uint8_t ep_open = cc->episode_open;
        const uint32_t ep_mis = cc->mis_ms;
        const uint32_t ep_clean = cc->clean_ms;
        const uint32_t ep_b0 = cc->mis_bins[0];
        const uint32_t ep_b1 = cc->mis_bins[1];
        cc->cal_coarse = (uint8_t)(r->coarse != 0u ? 1u : (r->arc != 0u ? 2u : 0u));
        magcal_cont_install(cc, &cc->cand, r->radius, r->est_noise_deg / MAGCAL_DEG_PER_RAD_F);
        cc->cal_conv = 0u;
        cc->cal_lv = cc->tc_on; /* fitted on levelled samples (a relevel's store holds only those) */
        cc->cal_tx = cc->st_tx; /* the tilt its fit saw (cont_relevel levels it by k times that) */
        cc->cal_ty = cc->st_ty;
        cc->cal_ts = sqrtf(fmaxf(cc->st_t2 - cc->st_tx * cc->st_tx - cc->st_ty * cc->st_ty, 0.0f));
        cc->cal_tk = (uint8_t)(cc->st_tn >= CONT_TF_MIN ? 1u : 0u);
        cc->relevel = 0u;
        if (ep_open != 0u) {
            cc->episode_open = ep_open;
            cc->mis_ms = ep_mis;
            cc->clean_ms = ep_clean;
            cc->mis_bins[0] = ep_b0;
            cc->mis_bins[1] = ep_b1;
        }
        cc->generation++;
        cc->adopted_err = r->est_heading_err_deg;
        cc->adopted_tilt = cc->solver.model_deg;
        magcal_cont_fit_begin(cc); /* the fit runs in step()'s slices (cont_step.c), the drain paused */
        cc->stored_at_adopt = (cc->store.ctr.added + cc->store.ctr.replaced);
        cc->age_ms_acc = 0u;
        cc->state = (uint8_t)MAGCAL_CONT_COLLECTING;
        return MAGCAL_CONT_ADOPTED;
    }
    if (st == MAGCAL_ERR_INCONSISTENT) {
        /* the store holds two installations (calibrator.h cfg.max_inconsistent_frac): the older
         * one is the past, so the next snapshot (started at once) cuts at half the oldest stored
         * sample's age and drops what is older, and what lies off the refused fit's ring (a store
         * that spans a change: the cut lands after the older part's youngest samples, or the next
         * INCONSISTENT solve cuts again, each cut dropping at least the oldest sample); the
         * calibration in force is untouched */
        cc->drop_changes = cc->changes;
        cc->drop_c = r->ellipse.center;
        cc->drop_r = magcal_isfinite_f(r->radius) && r->radius > 0.0f ? r->radius : 0.0f;
        cc->drop_on = 1u;
    }
    if (st == MAGCAL_ERR_NOT_BETTER) {
        if (cc->fz_on == 0u && cc->fit_phase == 0u && magcal_cont_no_gravity(cc) != 0) {
            /* fresh data confirm a calibration without a field model (restored at init): fit it
             * on this store, so that without gravity the slopes are measured (unmeasured, they
             * hold every heading TILTED: continuous.h "Slopes without gravity") */
            magcal_cont_fit_begin(cc);
        }
        if (r->coarse == 0u && r->arc == 0u && cc->cal_coarse == 0u && magcal_isfinite_f(r->current_err_deg) &&
            magcal_isfinite_f(r->est_heading_err_deg)) {
            /* the installed calibration's error as this solve measured it on its fresh data, as
             * good as its reference (continuous.h "OK tolerance") */
            cc->adopted_err = sqrtf(r->current_err_deg * r->current_err_deg +
                                    r->est_heading_err_deg * r->est_heading_err_deg);
            cc->adopted_tilt = cc->solver.model_deg;
        }
        /* fresh data confirm the installed calibration: a declared change is refuted; a relevel's
         * levelled store confirms it as a levelled one */
        if (cc->relevel != 0u) {
            if (cc->cal_conv != 0u) {
                /* the levelled store confirms the calibration levelled by its fit tilt */
                cc->cal.offset.x -= cc->tc_kl * cc->cal_tx;
                cc->cal.offset.y -= cc->tc_kl * cc->cal_ty;
                cc->cal_conv = 0u;
            }
            cc->cal_lv = 1u;
            cc->relevel = 0u;
        }
        cc->state = (uint8_t)MAGCAL_CONT_COLLECTING;
        return MAGCAL_CONT_REFUSED;
    }
    return MAGCAL_CONT_FAILED;
}
