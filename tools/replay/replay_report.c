/* magcal-replay: table and JSON output of the report (field names: docs/replay.md). */
#include "replay_report.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cjson/cJSON.h>

/* ------------------------------------------------------------------ warnings */

void replay_warn(replay_warnings_t *ws, const char *id, const char *fmt, ...)
{
    char text[sizeof ws->w[0].text];
    va_list ap;
    va_start(ap, fmt);
    (void)vsnprintf(text, sizeof text, fmt, ap);
    va_end(ap);
    fprintf(stderr, "magcal-replay: warning: %s\n", text);
    if (ws->n < REPLAY_MAX_WARNINGS) {
        ws->w[ws->n].id = id;
        memcpy(ws->w[ws->n].text, text, sizeof text);
        ws->n++;
    }
}

/* The field unit as printed: the given one, or "dump units". */
static const char *unit_of(const replay_report_t *r) { return r->unit != NULL ? r->unit : "dump units"; }

/* ------------------------------------------------------------------ JSON */

/* Float32 results printed with 7 significant digits (what a float holds), not 17. */
static double sig7(double v)
{
    char buf[40];
    if (!isfinite(v)) {
        return v; /* cJSON prints null */
    }
    (void)snprintf(buf, sizeof buf, "%.7g", v);
    return strtod(buf, NULL);
}

static cJSON *pair(double a, double b)
{
    cJSON *arr = cJSON_CreateArray();
    if (arr != NULL) {
        cJSON_AddItemToArray(arr, cJSON_CreateNumber(sig7(a)));
        cJSON_AddItemToArray(arr, cJSON_CreateNumber(sig7(b)));
    }
    return arr;
}

static cJSON *vec3(const double *v)
{
    cJSON *arr = cJSON_CreateArray();
    size_t k;
    if (arr != NULL) {
        for (k = 0u; k < 3u; ++k) {
            cJSON_AddItemToArray(arr, cJSON_CreateNumber(sig7(v[k])));
        }
    }
    return arr;
}

static const char *const k_tilt_keys[REPLAY_TILT_COUNT] = {"ok", "free_fall", "accel_norm", "gimbal",
                                                          "zero_field", "no_accel"};

/* Fields of the 3-D calibration (3d and aided modes). */
static void add_3d(cJSON *o, const replay_report_t *r)
{
    cJSON *m = cJSON_CreateArray();
    size_t i;
    cJSON_AddItemToObject(o, "offset", vec3(r->off3));
    for (i = 0u; i < 3u; ++i) {
        cJSON_AddItemToArray(m, vec3(r->mat3[i]));
    }
    cJSON_AddItemToObject(o, "matrix", m);
    cJSON_AddNumberToObject(o, "field", sig7(r->field3));
}

static void add_tilt(cJSON *o, const replay_report_t *r)
{
    cJSON *t = cJSON_CreateObject(), *g = cJSON_CreateObject();
    size_t k;
    cJSON_AddStringToObject(t, "accel_unit", r->accel_unit);
    cJSON_AddStringToObject(t, "accel_unit_source", r->accel_unit_source);
    cJSON_AddNumberToObject(t, "accel_median_norm", sig7(r->accel_median_norm));
    cJSON_AddStringToObject(t, "field", r->tilt_field != NULL ? r->tilt_field : "");
    if (r->mode[0] == '2') {
        cJSON_AddNumberToObject(t, "z_offset", sig7(r->tilt_z_offset));
        cJSON_AddNumberToObject(t, "hz_level", sig7(r->tilt_hz_level));
        if (isfinite(r->inclination_deg)) {
            cJSON_AddNumberToObject(t, "inclination_deg", r->inclination_deg);
        }
    }
    for (k = 0u; k < REPLAY_TILT_COUNT; ++k) {
        cJSON_AddNumberToObject(g, k_tilt_keys[k], (double)r->tilt_counts[k]);
    }
    cJSON_AddItemToObject(t, "gates", g);
    cJSON_AddItemToObject(o, "tilt", t);
}

static void add_swing(cJSON *o, const replay_report_t *r)
{
    cJSON *s = cJSON_CreateObject();
    size_t k;
    cJSON_AddStringToObject(s, "status", r->swing_status != NULL ? r->swing_status : "error");
    cJSON_AddNumberToObject(s, "status_code", r->swing_status_code);
    cJSON_AddStringToObject(s, "model", r->swing_model != NULL ? r->swing_model : "smith");
    cJSON_AddStringToObject(s, "method", r->swing_method != NULL ? r->swing_method : "pairs");
    cJSON_AddItemToObject(s, "ref_rows", pair((double)r->ref_first, (double)r->ref_end));
    cJSON_AddNumberToObject(s, "n_ref", (double)r->swing_n_ref);
    cJSON_AddNumberToObject(s, "n_points", (double)r->swing_n_points);
    if (r->swing_ncoef > 0u) {
        cJSON *c = cJSON_CreateArray();
        for (k = 0u; k < r->swing_ncoef; ++k) {
            cJSON_AddItemToArray(c, cJSON_CreateNumber(sig7(r->swing_coef[k])));
        }
        cJSON_AddItemToObject(s, "coefficients_deg", c);
        if (r->swing_model != NULL && r->swing_model[0] == 'f') {
            cJSON_AddNumberToObject(s, "order", (double)r->swing_order);
        }
        cJSON_AddNumberToObject(s, "fit_rms_deg", sig7(r->swing_fit_rms_deg));
        cJSON_AddNumberToObject(s, "fit_max_abs_deg", sig7(r->swing_fit_max_deg));
    }
    cJSON_AddItemToObject(o, "swing", s);
}

static void add_aided(cJSON *o, const replay_report_t *r)
{
    cJSON *a = cJSON_CreateObject(), *g = cJSON_CreateObject();
    cJSON_AddStringToObject(a, "status", r->aided_status != NULL ? r->aided_status : "error");
    cJSON_AddStringToObject(a, "field_unit", r->field_unit != NULL ? r->field_unit : "uT");
    cJSON_AddStringToObject(a, "prior", r->prior != NULL ? r->prior : "identity");
    cJSON_AddStringToObject(a, "objective", r->aided_objective != NULL ? r->aided_objective : "combined");
    cJSON_AddStringToObject(a, "model", r->geomag_model != NULL ? r->geomag_model : "WMM2025");
    if (r->prior != NULL && r->prior_g_scale != 1.0) {
        cJSON_AddNumberToObject(a, "prior_g_scale", sig7(r->prior_g_scale));
    }
    cJSON_AddItemToObject(a, "b_ref_ned_first", vec3(r->b_ref_first));
    cJSON_AddNumberToObject(a, "declination_first_deg", sig7(r->decl_first_deg));
    cJSON_AddNumberToObject(a, "n_seen", (double)r->aided_seen);
    cJSON_AddNumberToObject(a, "n_accepted", (double)r->aided_accepted);
    cJSON_AddNumberToObject(a, "n_skipped", (double)r->aided_skipped);
    cJSON_AddNumberToObject(g, "dop", (double)r->aided_gated[1]);
    cJSON_AddNumberToObject(g, "raw", (double)r->aided_gated[2]);
    cJSON_AddNumberToObject(g, "field", (double)r->aided_gated[3]);
    cJSON_AddNumberToObject(g, "vector", (double)r->aided_gated[4]);
    cJSON_AddItemToObject(a, "gated", g);
    if (r->have_aided) {
        cJSON_AddNumberToObject(a, "converged_at", (double)r->converged_at);
        cJSON_AddNumberToObject(a, "converged_row", (double)r->converged_row);
        cJSON_AddNumberToObject(a, "n_prior_dirs", (double)r->n_prior_dirs);
        cJSON_AddNumberToObject(a, "min_eig", sig7(r->min_eig));
        cJSON_AddNumberToObject(a, "weak_std", sig7(r->weak_std));
        cJSON_AddNumberToObject(a, "resid_rms", sig7(r->resid_rms_aided));
        cJSON_AddNumberToObject(a, "resid_f_rms", sig7(r->resid_f_rms_aided));
        cJSON_AddNumberToObject(a, "n_total_field", (double)r->n_total_field);
    }
    cJSON_AddItemToObject(o, "aided", a);
}

int replay_print_json(const replay_report_t *r)
{
    cJSON *o = cJSON_CreateObject();
    char *text;
    size_t g;
    if (o == NULL) {
        return -1;
    }
    cJSON_AddStringToObject(o, "status", r->status);
    if (r->reason[0] != '\0') {
        cJSON_AddStringToObject(o, "reason", r->reason);
    }
    cJSON_AddNumberToObject(o, "status_code", r->status_code);
    cJSON_AddStringToObject(o, "mode", r->mode);
    cJSON_AddStringToObject(o, "file", r->file);
    cJSON_AddStringToObject(o, "filter", r->filter);
    if (isfinite(r->eps)) {
        cJSON_AddNumberToObject(o, "eps", r->eps);
    }
    if (r->min_pts > 0) {
        cJSON_AddNumberToObject(o, "min_pts", (double)r->min_pts);
    }
    cJSON_AddStringToObject(o, "plane", r->plane);
    cJSON_AddNumberToObject(o, "declination_deg", r->declination_deg);
    cJSON_AddStringToObject(o, "field_unit", r->unit != NULL ? r->unit : "dump");
    cJSON_AddStringToObject(o, "separator", r->sep == ';' ? ";" : r->sep == '\t' ? "tab" : ",");
    if (r->mode[0] == '2') {
        cJSON_AddStringToObject(o, "fit", r->fit != NULL ? r->fit : "consensus");
    }
    cJSON_AddItemToObject(o, "cal_range", pair((double)r->cal_first, (double)r->cal_end));
    cJSON_AddNumberToObject(o, "n_rows", (double)r->n_rows);
    cJSON_AddNumberToObject(o, "n_cal", (double)r->n_cal);
    cJSON_AddNumberToObject(o, "n_fed", (double)r->n_fed);
    cJSON_AddNumberToObject(o, "decimation", (double)r->decimation);
    if (r->mode[0] == '2') {
        cJSON_AddNumberToObject(o, "capacity", (double)r->capacity);
    }
    /* reached by most failing runs too (0 where the run stopped earlier) */
    cJSON_AddNumberToObject(o, "n_used", (double)r->n_used);
    cJSON_AddNumberToObject(o, "n_outliers", (double)r->n_outliers);
    if (r->mode[0] != '2' && (r->have_3d || r->have_aided)) {
        cJSON_AddNumberToObject(o, "n_outlier_rows", (double)r->n_outlier_rows);
    }
    if (r->mode[0] == '2') {
        cJSON *ms = cJSON_CreateObject();
        cJSON_AddNumberToObject(o, "coverage_deg", sig7(r->coverage_deg));
        cJSON_AddNumberToObject(ms, "start_deg", sig7(r->missing_start_deg));
        cJSON_AddNumberToObject(ms, "width_deg", sig7(r->missing_width_deg));
        cJSON_AddItemToObject(o, "missing_sector", ms);
        if (isfinite(r->est_heading_err_deg)) {
            cJSON_AddNumberToObject(o, "est_heading_err_deg", sig7(r->est_heading_err_deg));
        } else {
            cJSON_AddNullToObject(o, "est_heading_err_deg");
        }
        if (r->adopt_rule != NULL) {
            cJSON_AddStringToObject(o, "adopt_rule", r->adopt_rule);
        }
    } else if (r->mode[0] == '3') {
        cJSON_AddNumberToObject(o, "coverage", sig7(r->coverage3));
    }
    if (r->have_3d) {
        add_3d(o, r);
        if (r->mode[0] == '3') {
            cJSON *dn = cJSON_CreateObject();
            cJSON_AddNumberToObject(dn, "rejected", (double)r->n_density3);
            if (isfinite(r->eps3)) {
                cJSON_AddNumberToObject(dn, "eps", sig7(r->eps3));
                cJSON_AddNumberToObject(dn, "eps_prime", sig7(r->eps_prime3));
                cJSON_AddNumberToObject(dn, "min_pts", (double)r->min_pts3);
            }
            cJSON_AddItemToObject(o, "density", dn);
            cJSON_AddNumberToObject(o, "n_residual_rejected", (double)r->n_rejected3);
            cJSON_AddStringToObject(o, "model", r->model3);
            cJSON_AddNumberToObject(o, "residual_rms", sig7(r->residual_rms));
        }
        cJSON_AddNumberToObject(o, "radius_spread_raw", sig7(r->spread_raw_all));
        cJSON_AddNumberToObject(o, "radius_spread_corrected", sig7(r->spread_corrected));
    }
    if (r->mode[0] == 'a') {
        add_aided(o, r);
    }
    if (r->tilt_on) {
        add_tilt(o, r);
    }
    if (r->have_geometry) {
        cJSON *m = cJSON_CreateArray();
        cJSON *e = cJSON_CreateObject();
        cJSON_AddItemToObject(o, "center", pair(r->center[0], r->center[1]));
        cJSON_AddItemToArray(m, pair(r->correction[0][0], r->correction[0][1]));
        cJSON_AddItemToArray(m, pair(r->correction[1][0], r->correction[1][1]));
        cJSON_AddItemToObject(o, "correction", m);
        cJSON_AddItemToObject(e, "center", pair(r->ell_center[0], r->ell_center[1]));
        cJSON_AddItemToObject(e, "semi_axes", pair(r->semi_axes[0], r->semi_axes[1]));
        cJSON_AddNumberToObject(e, "angle_deg", sig7(r->angle_deg));
        cJSON_AddItemToObject(o, "ellipse", e);
        cJSON_AddNumberToObject(o, "radius", sig7(r->radius));
        cJSON_AddNumberToObject(o, "residual_rms", sig7(r->residual_rms));
        /* The interface's radius_spread_raw is over every raw calibration sample (outliers
         * included); radius_spread_raw_used is over the samples the fit used (same set as the
         * corrected spread, so their ratio measures the correction alone). */
        cJSON_AddNumberToObject(o, "radius_spread_raw", sig7(r->spread_raw_all));
        cJSON_AddNumberToObject(o, "radius_spread_raw_used", sig7(r->spread_raw));
        cJSON_AddNumberToObject(o, "radius_spread_corrected", sig7(r->spread_corrected));
    }
    if (r->truth_column != NULL) {
        cJSON *t = cJSON_CreateObject();
        cJSON_AddStringToObject(t, "column", r->truth_column);
        cJSON_AddNumberToObject(t, "flagged", (double)r->truth_flagged);
        cJSON_AddNumberToObject(t, "detected", (double)r->truth_detected);
        cJSON_AddNumberToObject(t, "missed", (double)r->truth_missed);
        cJSON_AddNumberToObject(t, "false_alarms", (double)r->false_alarms);
        cJSON_AddItemToObject(o, "truth_flags", t);
    }
    if (r->swing_requested && (r->have_geometry || r->have_3d)) {
        add_swing(o, r);
        if (r->n_heading_before > 0u) {
            cJSON_AddNumberToObject(o, "n_heading_before_swing", (double)r->n_heading_before);
            cJSON_AddNumberToObject(o, "heading_rms_deg_before_swing", sig7(r->rms_before));
            cJSON_AddNumberToObject(o, "heading_bias_deg_before_swing", sig7(r->bias_before));
            cJSON_AddNumberToObject(o, "heading_max_abs_deg_before_swing", sig7(r->max_before));
        }
    }
    if ((r->have_geometry || r->have_3d) && r->n_heading > 0u) {
        cJSON *arr = cJSON_CreateArray();
        cJSON_AddNumberToObject(o, "n_heading", (double)r->n_heading);
        cJSON_AddNumberToObject(o, "n_heading_flagged", (double)r->n_heading_flagged);
        cJSON_AddNumberToObject(o, "heading_rms_deg", sig7(r->heading_rms_deg));
        cJSON_AddNumberToObject(o, "heading_bias_deg", sig7(r->heading_bias_deg));
        cJSON_AddNumberToObject(o, "heading_max_abs_deg", sig7(r->heading_max_abs_deg));
        for (g = 0u; g < r->n_groups; ++g) {
            cJSON *it = cJSON_CreateObject();
            cJSON_AddNumberToObject(it, "ref_deg", sig7(r->groups[g].ref_deg));
            cJSON_AddNumberToObject(it, "n", (double)r->groups[g].n);
            cJSON_AddNumberToObject(it, "rms_deg", sig7(r->groups[g].rms_deg));
            cJSON_AddNumberToObject(it, "bias_deg", sig7(r->groups[g].bias_deg));
            cJSON_AddNumberToObject(it, "max_abs_deg", sig7(r->groups[g].max_abs_deg));
            cJSON_AddItemToArray(arr, it);
        }
        cJSON_AddItemToObject(o, "heading_rms_by_ref", arr);
        cJSON_AddStringToObject(o, "heading_by_ref_grouping", r->by_ref_sectors ? "sector45" : "exact");
    }
    {
        cJSON *wa = cJSON_CreateArray();
        for (g = 0u; g < r->warnings.n; ++g) {
            cJSON *it = cJSON_CreateObject();
            cJSON_AddStringToObject(it, "id", r->warnings.w[g].id);
            cJSON_AddStringToObject(it, "text", r->warnings.w[g].text);
            cJSON_AddItemToArray(wa, it);
        }
        cJSON_AddItemToObject(o, "warnings", wa);
    }
    text = cJSON_PrintUnformatted(o);
    cJSON_Delete(o);
    if (text == NULL) {
        return -1;
    }
    if (printf("%s\n", text) < 0) {
        cJSON_free(text);
        return -1;
    }
    cJSON_free(text);
    return 0;
}

/* ------------------------------------------------------------------ table */

static void print_2d(const replay_report_t *r);
static void print_headings(const replay_report_t *r);

static void print_tilt(const replay_report_t *r)
{
    size_t k;
    printf("  tilt              on: accelerometer in %s (%s; median |a| %.4g); %s\n", r->accel_unit,
           r->accel_unit_source, r->accel_median_norm, r->tilt_field != NULL ? r->tilt_field : "");
    if (r->mode[0] == '2') {
        printf("                    z_offset %.6g (mean mz over the calibration inliers), hz_level %.6g (%s)\n",
               r->tilt_z_offset, r->tilt_hz_level,
               isfinite(r->inclination_deg) ? "from --inclination" : "no --inclination: taken as 0");
    }
    printf("                    gates:");
    for (k = 0u; k < REPLAY_TILT_COUNT; ++k) {
        static const char *const names[REPLAY_TILT_COUNT] = {"ok", "free_fall", "accel_norm", "gimbal",
                                                            "zero_field", "no_accel"};
        printf(" %s %lu", names[k], (unsigned long)r->tilt_counts[k]);
    }
    printf("\n");
}

static void print_3d(const replay_report_t *r)
{
    printf("  offset V          (%.6g, %.6g, %.6g) %s\n", r->off3[0], r->off3[1], r->off3[2], unit_of(r));
    printf("  matrix G          [%.6g %.6g %.6g; %.6g %.6g %.6g; %.6g %.6g %.6g]  h = G (m - V)\n",
           r->mat3[0][0], r->mat3[0][1], r->mat3[0][2], r->mat3[1][0], r->mat3[1][1], r->mat3[1][2],
           r->mat3[2][0], r->mat3[2][1], r->mat3[2][2]);
    printf("  field F           %.6g %s\n", r->field3, unit_of(r));
    if (r->mode[0] == '3') {
        if (isfinite(r->eps3)) {
            printf("  density stage     3-D OPTICS (%s): eps %.6g, eps' %.6g, MinPts %ld: %lu rejected; residual gate: %lu\n",
                   r->filter, r->eps3, r->eps_prime3, r->min_pts3, (unsigned long)r->n_density3,
                   (unsigned long)r->n_rejected3);
        } else {
            printf("  density stage     %s; residual gate: %lu rejected\n", r->filter, (unsigned long)r->n_rejected3);
        }
        printf("  model             %s; direction coverage %.3f of 72 cells; residual RMS %.6g (%.2f %% of F)\n",
               r->model3, r->coverage3, r->residual_rms,
               r->field3 > 0.0 ? 100.0 * r->residual_rms / r->field3 : NAN);
    }
    printf("  radius spread     raw %.2f %% -> corrected %.2f %% over every calibration row (3-D norms; %.1fx smaller)\n",
           100.0 * r->spread_raw_all, 100.0 * r->spread_corrected,
           r->spread_corrected > 0.0 ? r->spread_raw_all / r->spread_corrected : INFINITY);
}

static void print_aided(const replay_report_t *r)
{
    printf("  aided             %s; %lu epochs seen, %lu accepted, %lu skipped (missing cells); field unit %s\n",
           r->aided_status != NULL ? r->aided_status : "error", (unsigned long)r->aided_seen,
           (unsigned long)r->aided_accepted, (unsigned long)r->aided_skipped,
           r->field_unit != NULL ? r->field_unit : "uT");
    printf("  objective         %s\n", r->aided_objective != NULL ? r->aided_objective : "combined");
    printf("  prior             %s", r->prior != NULL ? r->prior : "identity");
    if (r->prior != NULL && r->prior_g_scale != 1.0) {
        printf(" (a 3d report: G scaled by |B_ref| / F = %.6g)", r->prior_g_scale);
    }
    printf("\n");
    printf("  gated             dop %lu, raw %lu, field %lu, vector %lu\n", (unsigned long)r->aided_gated[1],
           (unsigned long)r->aided_gated[2], (unsigned long)r->aided_gated[3], (unsigned long)r->aided_gated[4]);
    printf("  B_ref (first)     NED (%.6g, %.6g, %.6g), declination %.3f deg (%s)\n", r->b_ref_first[0],
           r->b_ref_first[1], r->b_ref_first[2], r->decl_first_deg,
           r->geomag_model != NULL ? r->geomag_model : "WMM2025");
    if (r->have_aided) {
        printf("  convergence       at accepted epoch %ld (row %ld); %u directions from the prior; "
               "min_eig %.3g, weak_std %.3g, residual RMS %.4g\n",
               r->converged_at, r->converged_row, r->n_prior_dirs, r->min_eig, r->weak_std, r->resid_rms_aided);
        printf("  total field       %lu epochs in the objective; a-priori |G(m - V)| - |B_ref| RMS %.4g\n",
               (unsigned long)r->n_total_field, r->resid_f_rms_aided);
    }
}

static void print_swing(const replay_report_t *r)
{
    size_t k;
    printf("  swing             rows [%lu, %lu): %s (%s, %s); %lu reference rows, %lu fit points\n",
           (unsigned long)r->ref_first, (unsigned long)r->ref_end, r->swing_status, r->swing_model,
           r->swing_method, (unsigned long)r->swing_n_ref, (unsigned long)r->swing_n_points);
    if (r->swing_ncoef > 0u) {
        printf("                    coefficients (deg):");
        for (k = 0u; k < r->swing_ncoef; ++k) {
            printf(" %+.4f", r->swing_coef[k]);
        }
        printf("; fit RMS %.3f deg, max %.3f deg\n", r->swing_fit_rms_deg, r->swing_fit_max_deg);
    }
    if (r->n_heading_before > 0u) {
        printf("  before swing      %lu rows: RMS %.3f deg, bias %+.3f deg, max |e| %.3f deg\n",
               (unsigned long)r->n_heading_before, r->rms_before, r->bias_before, r->max_before);
    }
}

static void print_body(const replay_report_t *r);

void replay_print_table(const replay_report_t *r)
{
    size_t k;
    print_body(r);
    for (k = 0u; k < r->warnings.n; ++k) {
        printf("  warning           %s\n", r->warnings.w[k].text);
    }
}

static void print_body(const replay_report_t *r)
{
    printf("magcal-replay %s (mode %s; field unit %s)\n", r->file, r->mode, unit_of(r));
    printf("  status            %s%s%s\n", r->status, r->reason[0] ? ": " : "", r->reason);
    printf("  rows              %lu; calibration rows [%lu, %lu) = %lu", (unsigned long)r->n_rows,
           (unsigned long)r->cal_first, (unsigned long)r->cal_end, (unsigned long)r->n_cal);
    if (r->decimation > 1u) {
        printf(", every %lu-th fed (%lu; capacity %lu)", (unsigned long)r->decimation,
               (unsigned long)r->n_fed, (unsigned long)r->capacity);
    }
    printf("\n");
    printf("  filter            %s", r->filter);
    if (isfinite(r->eps) || r->min_pts > 0) {
        printf(" (");
        if (isfinite(r->eps)) {
            printf("eps %g", r->eps);
        }
        if (r->min_pts > 0) {
            printf("%smin_pts %ld", isfinite(r->eps) ? ", " : "", r->min_pts);
        }
        printf(")");
    }
    printf("; plane %s; declination %g deg\n", r->plane, r->declination_deg);
    if (r->mode[0] != '2') {
        printf("  samples           %lu fed, %lu used, %lu rejected\n", (unsigned long)r->n_fed,
               (unsigned long)r->n_used, (unsigned long)r->n_outliers);
        if (r->have_3d) {
            printf("  outlier rows      %lu of %lu rows (headings CSV outlier = 1: %s)\n",
                   (unsigned long)r->n_outlier_rows, (unsigned long)r->n_rows,
                   r->mode[0] == 'a' ? "epochs rejected by a gate"
                                     : "3-D OPTICS density stage or the fit's final residual gate on the "
                                       "calibration rows, the fit's gate on the others");
        }
        if (r->truth_column != NULL) {
            printf("  truth flags       %lu fed rows have %s=1: %lu flagged, %lu missed; %lu false alarms\n",
                   (unsigned long)r->truth_flagged, r->truth_column, (unsigned long)r->truth_detected,
                   (unsigned long)r->truth_missed, (unsigned long)r->false_alarms);
        }
        if (r->mode[0] == 'a') {
            print_aided(r);
        }
        if (r->have_3d) {
            print_3d(r);
        } else if (r->mode[0] == '3') {
            printf("  coverage          %.3f of 72 direction cells (about the sample mean)\n", r->coverage3);
        }
        if (!r->have_3d) {
            return;
        }
    } else if (!r->have_geometry) {
        printf("  samples           %lu fed, %lu used, %lu outliers; arc coverage %.0f deg\n",
               (unsigned long)r->n_fed, (unsigned long)r->n_used, (unsigned long)r->n_outliers,
               r->coverage_deg);
        return;
    }
    if (r->mode[0] == '2') {
        print_2d(r);
    }
    if (r->tilt_on) {
        print_tilt(r);
    }
    if (r->swing_requested) {
        print_swing(r);
    }
    if (r->n_heading == 0u) {
        printf("  heading vs ref    no reference headings outside the calibration%s rows\n",
               r->swing_requested ? " and reference" : "");
        return;
    }
    print_headings(r);
}

static void print_2d(const replay_report_t *r)
{
    printf("  samples used      %lu of %lu fed (%lu outliers)\n", (unsigned long)r->n_used,
           (unsigned long)r->n_fed, (unsigned long)r->n_outliers);
    if (r->truth_column != NULL) {
        printf("  truth flags       %lu fed rows have %s=1: %lu flagged, %lu missed; %lu false alarms\n",
               (unsigned long)r->truth_flagged, r->truth_column, (unsigned long)r->truth_detected,
               (unsigned long)r->truth_missed, (unsigned long)r->false_alarms);
    }
    printf("  arc coverage      %.0f deg", r->coverage_deg);
    if (r->missing_width_deg > 0.0) {
        printf("; largest gap %.0f deg from heading %.0f deg", r->missing_width_deg, r->missing_start_deg);
    }
    printf("\n");
    printf("  est. heading err  %.3g deg (the library's estimate; needs no reference)\n", r->est_heading_err_deg);
    printf("  fit, adoption     %s fit; adopted by rule %s\n", r->fit != NULL ? r->fit : "consensus",
           r->adopt_rule != NULL ? r->adopt_rule : "?");
    printf("  hard-iron centre  (%.6g, %.6g) %s\n", r->center[0], r->center[1], unit_of(r));
    printf("  ellipse           semi-axes %.6g / %.6g, major axis at %.1f deg (ccw from +x)\n",
           r->semi_axes[0], r->semi_axes[1], r->angle_deg);
    printf("  correction M      [%.6g %.6g; %.6g %.6g]  h = M (raw - centre)\n", r->correction[0][0],
           r->correction[0][1], r->correction[1][0], r->correction[1][1]);
    printf("  radius            %.6g %s (corrected field magnitude)\n", r->radius, unit_of(r));
    printf("  residual RMS      %.6g %s (%.2f %% of radius)\n", r->residual_rms, unit_of(r),
           r->radius > 0.0 ? 100.0 * r->residual_rms / r->radius : NAN);
    printf("  radius spread     raw %.2f %% -> corrected %.2f %% over the samples used (std/mean; %.1fx smaller)\n",
           100.0 * r->spread_raw, 100.0 * r->spread_corrected,
           r->spread_corrected > 0.0 ? r->spread_raw / r->spread_corrected : INFINITY);
    if (r->n_outliers > 0u) {
        printf("                    raw %.2f %% over every fed calibration sample, outliers included\n",
               100.0 * r->spread_raw_all);
    }
}

static void print_headings(const replay_report_t *r)
{
    size_t g;
    printf("  heading vs ref    %lu rows%s: RMS %.3f deg, bias %+.3f deg, max |e| %.3f deg",
           (unsigned long)r->n_heading, r->swing_ncoef > 0u ? " (after the swing)" : "", r->heading_rms_deg, r->heading_bias_deg,
           r->heading_max_abs_deg);
    if (r->n_heading_flagged > 0u) {
        printf(" (%lu of them flagged as outliers, included)", (unsigned long)r->n_heading_flagged);
    }
    printf("\n");
    printf("      %s       n     RMS    bias   max|e|   (deg)\n", r->by_ref_sectors ? "sector" : "   ref");
    for (g = 0u; g < r->n_groups; ++g) {
        const replay_ref_group_t *q = &r->groups[g];
        printf("      %6.1f  %6lu  %6.3f  %+6.3f  %6.3f\n", q->ref_deg, (unsigned long)q->n,
               q->rms_deg, q->bias_deg, q->max_abs_deg);
    }
}
