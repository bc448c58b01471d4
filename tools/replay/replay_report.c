/* magcal-replay: table and JSON output of the report (field names: docs/replay.md). */
#include "replay_report.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include <cjson/cJSON.h>

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
    cJSON_AddItemToObject(o, "cal_range", pair((double)r->cal_first, (double)r->cal_end));
    cJSON_AddNumberToObject(o, "n_rows", (double)r->n_rows);
    cJSON_AddNumberToObject(o, "n_cal", (double)r->n_cal);
    cJSON_AddNumberToObject(o, "n_fed", (double)r->n_fed);
    cJSON_AddNumberToObject(o, "decimation", (double)r->decimation);
    cJSON_AddNumberToObject(o, "capacity", (double)r->capacity);
    /* reached by most failing runs too (0 where the run stopped earlier) */
    cJSON_AddNumberToObject(o, "n_used", (double)r->n_used);
    cJSON_AddNumberToObject(o, "n_outliers", (double)r->n_outliers);
    cJSON_AddNumberToObject(o, "coverage_deg", sig7(r->coverage_deg));
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
    if (r->have_geometry && r->n_heading > 0u) {
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

void replay_print_table(const replay_report_t *r)
{
    size_t g;
    printf("magcal-replay %s\n", r->file);
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
    if (!r->have_geometry) {
        printf("  samples           %lu fed, %lu used, %lu outliers; arc coverage %.0f deg\n",
               (unsigned long)r->n_fed, (unsigned long)r->n_used, (unsigned long)r->n_outliers,
               r->coverage_deg);
        return;
    }
    printf("  samples used      %lu of %lu fed (%lu outliers)\n", (unsigned long)r->n_used,
           (unsigned long)r->n_fed, (unsigned long)r->n_outliers);
    if (r->truth_column != NULL) {
        printf("  truth flags       %lu fed rows have %s=1: %lu flagged, %lu missed; %lu false alarms\n",
               (unsigned long)r->truth_flagged, r->truth_column, (unsigned long)r->truth_detected,
               (unsigned long)r->truth_missed, (unsigned long)r->false_alarms);
    }
    printf("  arc coverage      %.0f deg\n", r->coverage_deg);
    printf("  hard-iron centre  (%.6g, %.6g) dump units\n", r->center[0], r->center[1]);
    printf("  ellipse           semi-axes %.6g / %.6g, major axis at %.1f deg (ccw from +x)\n",
           r->semi_axes[0], r->semi_axes[1], r->angle_deg);
    printf("  correction M      [%.6g %.6g; %.6g %.6g]  h = M (raw - centre)\n", r->correction[0][0],
           r->correction[0][1], r->correction[1][0], r->correction[1][1]);
    printf("  radius            %.6g dump units (corrected field magnitude)\n", r->radius);
    printf("  residual RMS      %.6g dump units (%.2f %% of radius)\n", r->residual_rms,
           r->radius > 0.0 ? 100.0 * r->residual_rms / r->radius : NAN);
    printf("  radius spread     raw %.2f %% -> corrected %.2f %% over the samples used (std/mean; %.1fx smaller)\n",
           100.0 * r->spread_raw, 100.0 * r->spread_corrected,
           r->spread_corrected > 0.0 ? r->spread_raw / r->spread_corrected : INFINITY);
    if (r->n_outliers > 0u) {
        printf("                    raw %.2f %% over every fed calibration sample, outliers included\n",
               100.0 * r->spread_raw_all);
    }
    if (r->n_heading == 0u) {
        printf("  heading vs ref    no reference headings outside the calibration rows\n");
        return;
    }
    printf("  heading vs ref    %lu rows: RMS %.3f deg, bias %+.3f deg, max |e| %.3f deg",
           (unsigned long)r->n_heading, r->heading_rms_deg, r->heading_bias_deg,
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
