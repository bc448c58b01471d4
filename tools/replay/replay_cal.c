/* magcal-replay: drive the calibrator through the replay port (see replay_cal.h). */
#include "replay_cal.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "magcal_port_replay.h"

/* Firmware-style static storage: one calibrator at the library's largest capacity. */
#define REPLAY_CAP ((size_t)MAGCAL_MAX_SAMPLES)
static magcal_calibrator_t g_cal;
static magcal_vec2_t g_buf[MAGCAL_MAX_SAMPLES];
static uint32_t g_work[(MAGCAL_CALIBRATOR_WORKSPACE_LEN(MAGCAL_MAX_SAMPLES) + 3u) / 4u];

size_t replay_capacity(void) { return REPLAY_CAP; }

/* Machine-readable status names for the JSON `status` field (enum name, lower case). */
const char *replay_status_id(magcal_status_t st)
{
    switch (st) {
    case MAGCAL_OK: return "ok";
    case MAGCAL_ERR_NULL: return "null";
    case MAGCAL_ERR_ARG: return "arg";
    case MAGCAL_ERR_WORKSPACE: return "workspace";
    case MAGCAL_ERR_NONFINITE: return "nonfinite";
    case MAGCAL_ERR_TOO_FEW_POINTS: return "too_few_points";
    case MAGCAL_ERR_DEGENERATE: return "degenerate";
    case MAGCAL_ERR_COVERAGE: return "coverage";
    case MAGCAL_ERR_HYPERBOLA: return "hyperbola";
    case MAGCAL_ERR_PARABOLA: return "parabola";
    case MAGCAL_ERR_IMAGINARY: return "imaginary";
    case MAGCAL_ERR_ILL_CONDITIONED: return "ill_conditioned";
    case MAGCAL_ERR_BUFFER_FULL: return "buffer_full";
    case MAGCAL_ERR_ALL_NOISE: return "all_noise";
    case MAGCAL_ERR_TOO_MANY_OUTLIERS: return "too_many_outliers";
    case MAGCAL_ERR_RADIUS_RANGE: return "radius_range";
    case MAGCAL_ERR_AXIS_RATIO: return "axis_ratio";
    case MAGCAL_ERR_RESIDUAL: return "residual";
    case MAGCAL_ERR_NOT_BETTER: return "not_better";
    case MAGCAL_ERR_PORT: return "port";
    case MAGCAL_ERR_TIMEOUT: return "timeout";
    case MAGCAL_ERR_NO_DATA: return "no_data";
    case MAGCAL_ERR_STATE: return "state";
    case MAGCAL_ERR_NOT_INITIALISED: return "not_initialised";
    case MAGCAL_ERR_FREE_FALL: return "free_fall";
    case MAGCAL_ERR_ACCEL_NORM: return "accel_norm";
    case MAGCAL_ERR_GIMBAL: return "gimbal";
    case MAGCAL_ERR_SPREAD: return "spread";
    case MAGCAL_ERR_THRESHOLD: return "threshold";
    case MAGCAL_ERR_OUT_OF_VALIDITY: return "out_of_validity";
    case MAGCAL_ERR_NOT_ELLIPSOID: return "not_ellipsoid";
    case MAGCAL_ERR_UNOBSERVABLE: return "unobservable";
    case MAGCAL_ERR_NOT_CONVERGED: return "not_converged";
    case MAGCAL_ERR_ZERO_FIELD: return "zero_field";
    case MAGCAL_ERR_GATED: return "gated";
    case MAGCAL_ERR_NO_MOTION: return "no_motion";
    case MAGCAL_ERR_SINGLE_AXIS: return "single_axis";
    case MAGCAL_ERR_FIELD_MAGNITUDE: return "field_magnitude";
    case MAGCAL_ERR_INCONSISTENT: return "inconsistent";
    case MAGCAL_ERR_SHAPE_CHANGED: return "shape_changed";
    default: return "error";
    }
}

/* Human-readable reason of a failed run, with the numbers that decided it. */
static void explain(magcal_status_t st, const magcal_calibrator_cfg_t *cfg,
                    const magcal_cal_report_t *rep, char *out, size_t len)
{
    switch (st) {
    case MAGCAL_ERR_TOO_FEW_POINTS:
        (void)snprintf(out, len, "%s: %u samples, %u usable; at least %u needed",
                       magcal_status_str(st), (unsigned)rep->samples, (unsigned)rep->used,
                       (unsigned)cfg->min_samples);
        break;
    case MAGCAL_ERR_COVERAGE:
        (void)snprintf(out, len,
                       "%s: the samples cover %.0f deg of the turn, %.0f deg needed; largest gap %.0f deg "
                       "from heading %.0f deg (turn the vehicle through a full circle)",
                       magcal_status_str(st), (double)rep->coverage_deg, (double)cfg->min_coverage_deg,
                       (double)rep->missing_width_deg, (double)rep->missing_start_deg);
        break;
    case MAGCAL_ERR_TOO_MANY_OUTLIERS:
        (void)snprintf(out, len, "%s: %u of %u samples rejected (filter %u, residual %u), more than %.0f %%",
                       magcal_status_str(st), (unsigned)(rep->samples - rep->used), (unsigned)rep->samples,
                       (unsigned)rep->rejected_filter, (unsigned)rep->rejected_consensus,
                       100.0 * (double)cfg->max_outlier_frac);
        break;
    case MAGCAL_ERR_AXIS_RATIO:
        (void)snprintf(out, len, "%s: semi-axis ratio %.3f below the limit %.3f (strong soft iron or tilt)",
                       magcal_status_str(st), (double)rep->axis_ratio, (double)cfg->min_axis_ratio);
        break;
    case MAGCAL_ERR_RESIDUAL:
        (void)snprintf(out, len, "%s: fit residual %.3g = %.1f %% of the radius, limit %.1f %%",
                       magcal_status_str(st), (double)rep->residual_rms, 100.0 * (double)rep->residual_rel,
                       100.0 * (double)cfg->max_residual_rel);
        break;
    case MAGCAL_ERR_RADIUS_RANGE:
        (void)snprintf(out, len, "%s: radius %.6g outside [%.6g, %.6g]", magcal_status_str(st),
                       (double)rep->radius, (double)cfg->min_radius, (double)cfg->max_radius);
        break;
    default:
        (void)snprintf(out, len, "%s (%u samples)", magcal_status_str(st), (unsigned)rep->samples);
        break;
    }
}

/* ---- What the report says the calibration is worth. These two read the library's report in
 * ONE place each, so a change of magcal_cal_report_t (an honest estimate, an adoption-rule field)
 * is re-wired here only. */

/* Estimated heading error of the new calibration, degrees (calibrator.h, "Heading-error
 * estimates"); NaN when the run did not get that far. */
double replay_est_heading_err_deg(const magcal_cal_report_t *rep, magcal_status_t st)
{
    if (st != MAGCAL_OK && st != MAGCAL_ERR_NOT_BETTER) {
        return NAN;
    }
    return (double)rep->est_heading_err_deg;
}

/* The rule that adopted the calibration (the library's report names it, calibrator.h) or what
 * refused it: the adoption rule (NOT_BETTER) or a gate (its status). */
const char *replay_adopt_rule(const magcal_cal_report_t *rep, magcal_status_t st)
{
    if (st == MAGCAL_OK && rep->adopted != 0u) {
        return magcal_adopt_rule_str(rep->adopt_rule);
    }
    if (st == MAGCAL_ERR_NOT_BETTER) {
        return "refused: not better than the current calibration";
    }
    return "refused by a gate (status)";
}

static int set_filter(const replay_options_t *o, magcal_calibrator_cfg_t *cfg)
{
    if (o->plain) {
        /* The textbook baseline: no density filter and no residual stage, so run() fits every
         * sample with one unweighted 5-parameter least-squares fit (calibrator.h, stage 4). */
        cfg->filter = MAGCAL_FILTER_NONE;
        cfg->use_consensus = 0u;
        return 0;
    }
    if (strcmp(o->filter, "optics") == 0) {
        cfg->filter = MAGCAL_FILTER_OPTICS_GRID;
    } else if (strcmp(o->filter, "optics-classic") == 0) {
        cfg->filter = MAGCAL_FILTER_OPTICS_CLASSIC;
    } else if (strcmp(o->filter, "dbscan") == 0) {
        cfg->filter = MAGCAL_FILTER_DBSCAN;
    } else if (strcmp(o->filter, "none") == 0) {
        cfg->filter = MAGCAL_FILTER_NONE;
    } else {
        return -1;
    }
    if (isfinite(o->eps)) {
        cfg->eps = (float)o->eps;
    }
    if (o->min_pts > 0) {
        if (o->min_pts > (long)MAGCAL_MAX_MIN_PTS) {
            return -2;
        }
        cfg->min_pts = (uint16_t)o->min_pts;
    }
    return 0;
}

int replay_calibrate(const replay_options_t *o, const magcal_replay_csv_t *d, size_t first,
                     size_t n_fed, size_t step, replay_report_t *r, replay_result_t *res)
{
    magcal_calibrator_cfg_t cfg = MAGCAL_CALIBRATOR_CFG_DEFAULT;
    magcal_cal2d_t current = MAGCAL_CAL2D_IDENTITY;
    magcal_cal_report_t rep;
    magcal_vec3_t *mag;
    uint32_t *t_ms;
    magcal_status_t st;
    size_t i;
    int rc = REPLAY_EXIT_OK;

    res->have_fit = 0;
    r->status = "error";
    r->status_code = 0;
    if (n_fed > REPLAY_CAP) {
        snprintf(r->reason, sizeof r->reason, "internal: %lu rows exceed capacity", (unsigned long)n_fed);
        return REPLAY_EXIT_INTERNAL;
    }
    switch (set_filter(o, &cfg)) {
    case 0:
        break;
    case -2:
        fprintf(stderr, "magcal-replay: --min-pts %ld exceeds the library's MAGCAL_MAX_MIN_PTS (%u)\n",
                o->min_pts, (unsigned)MAGCAL_MAX_MIN_PTS);
        return REPLAY_EXIT_USAGE;
    default:
        fprintf(stderr, "magcal-replay: unknown filter %s\n", o->filter);
        return REPLAY_EXIT_USAGE;
    }
    st = magcal_calibrator_init(&g_cal, &cfg, g_buf, REPLAY_CAP, g_work, sizeof g_work);
    if (st == MAGCAL_ERR_ARG) {
        fprintf(stderr, "magcal-replay: the calibrator rejects the options (eps %s, min_pts %ld; 0 = "
                        "automatic): %s\n",
                isfinite(o->eps) ? "given" : "automatic", o->min_pts, magcal_status_str(st));
        return REPLAY_EXIT_USAGE;
    }
    if (st != MAGCAL_OK) {
        fprintf(stderr, "magcal-replay: magcal_calibrator_init: %s\n", magcal_status_str(st));
        return REPLAY_EXIT_INTERNAL;
    }

    /* The port borrows these arrays for the whole replay. */
    mag = (magcal_vec3_t *)calloc(n_fed, sizeof *mag);
    t_ms = (uint32_t *)calloc(n_fed, sizeof *t_ms);
    if (mag == NULL || t_ms == NULL) {
        free(mag);
        free(t_ms);
        fprintf(stderr, "magcal-replay: out of memory\n");
        return REPLAY_EXIT_INTERNAL;
    }
    if (magcal_replay_csv_fill(d, first, n_fed, step, &o->plane, mag, NULL, NULL) != MAGCAL_OK) {
        free(mag);
        free(t_ms);
        fprintf(stderr, "magcal-replay: internal error filling the replay arrays\n");
        return REPLAY_EXIT_INTERNAL;
    }
    /* timestamps when the dump has a usable t column (the clock is informational only) */
    if (magcal_replay_csv_fill(d, first, n_fed, step, &o->plane, mag, NULL, t_ms) != MAGCAL_OK) {
        free(t_ms);
        t_ms = NULL;
    }
    magcal_port_replay_start(mag, NULL, t_ms, n_fed, 0u);

    /* The firmware loop: one port sample per poll, until the replay is exhausted. */
    for (i = 0u; i <= n_fed; ++i) {
        st = magcal_calibrator_poll(&g_cal);
        if (st == MAGCAL_ERR_NO_DATA) {
            break;
        }
        if (st != MAGCAL_OK) {
            fprintf(stderr, "magcal-replay: magcal_calibrator_poll, row %lu: %s\n",
                    (unsigned long)(first + i * step), magcal_status_str(st));
            rc = REPLAY_EXIT_INTERNAL;
            break;
        }
    }
    if (rc == REPLAY_EXIT_OK && magcal_calibrator_count(&g_cal) != n_fed) {
        fprintf(stderr, "magcal-replay: calibrator stored %lu of %lu samples\n",
                (unsigned long)magcal_calibrator_count(&g_cal), (unsigned long)n_fed);
        rc = REPLAY_EXIT_INTERNAL;
    }
    if (rc != REPLAY_EXIT_OK) {
        free(mag);
        free(t_ms);
        return rc;
    }

    memset(&rep, 0, sizeof rep);
    st = magcal_calibrator_run(&g_cal, &current, &rep);
    free(mag);
    free(t_ms);
    magcal_port_replay_start(NULL, NULL, NULL, 0u, 0u);

    r->status = replay_status_id(st);
    r->status_code = (int)st;
    r->n_used = rep.used;
    r->n_outliers = rep.outliers;
    r->coverage_deg = rep.coverage_deg;
    r->missing_start_deg = rep.missing_start_deg;
    r->missing_width_deg = rep.missing_width_deg;
    r->est_heading_err_deg = replay_est_heading_err_deg(&rep, st);
    r->adopt_rule = replay_adopt_rule(&rep, st);
    r->filter_eps_used = rep.filter_eps;
    if (st != MAGCAL_OK) {
        explain(st, &cfg, &rep, r->reason, sizeof r->reason);
        r->have_geometry = 0;
        return (st == MAGCAL_ERR_ARG || st == MAGCAL_ERR_WORKSPACE) ? REPLAY_EXIT_USAGE
                                                                     : REPLAY_EXIT_CAL_FAILED;
    }
    res->cal = current;
    res->have_fit = 1;
    for (i = 0u; i < n_fed; ++i) {
        int inl = 1;
        if (magcal_calibrator_inlier(&g_cal, i, &inl) != MAGCAL_OK) {
            fprintf(stderr, "magcal-replay: magcal_calibrator_inlier(%lu) failed\n", (unsigned long)i);
            return REPLAY_EXIT_INTERNAL;
        }
        res->flags[i] = (unsigned char)(inl == 0);
    }
    r->have_geometry = 1;
    r->center[0] = current.offset.x;
    r->center[1] = current.offset.y;
    r->correction[0][0] = current.m[0][0];
    r->correction[0][1] = current.m[0][1];
    r->correction[1][0] = current.m[1][0];
    r->correction[1][1] = current.m[1][1];
    r->radius = current.radius;
    r->ell_center[0] = rep.ellipse.center.x;
    r->ell_center[1] = rep.ellipse.center.y;
    r->semi_axes[0] = rep.ellipse.semi_major;
    r->semi_axes[1] = rep.ellipse.semi_minor;
    {
        /* ellipse.h gives the semi-MINOR axis direction; report the major one, in (-90, 90] */
        double a = (double)rep.ellipse.angle_rad * (180.0 / 3.14159265358979323846) + 90.0;
        while (a > 90.0) {
            a -= 180.0;
        }
        while (a <= -90.0) {
            a += 180.0;
        }
        r->angle_deg = a;
    }
    r->residual_rms = rep.residual_rms;
    return REPLAY_EXIT_OK;
}

int replay_classify(const replay_result_t *res, magcal_vec2_t raw)
{
    int out = 0;
    if (!res->have_fit || magcal_calibrator_classify(&g_cal, raw, &out) != MAGCAL_OK) {
        return 0;
    }
    return out != 0;
}
