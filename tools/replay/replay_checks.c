/* magcal-replay: plausibility checks (see replay_checks.h; thresholds in docs/replay.md). */
#include "replay_checks.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const double k_pi = 3.14159265358979323846;
static const double k_deg = 57.295779513082320876798;

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* Median of v[0..k) (sorted in place); NaN when k == 0. */
static double median(double *v, size_t k)
{
    if (k == 0u) {
        return NAN;
    }
    qsort(v, k, sizeof *v, cmp_double);
    return (k % 2u) ? v[k / 2u] : 0.5 * (v[k / 2u - 1u] + v[k / 2u]);
}

/* Value at fraction q (0..1) of v[0..k) (sorts in place). */
static double quantile(double *v, size_t k, double q)
{
    size_t i;
    if (k == 0u) {
        return NAN;
    }
    qsort(v, k, sizeof *v, cmp_double);
    i = (size_t)floor(q * (double)(k - 1u) + 0.5);
    return v[i];
}

void replay_check_columns(const magcal_replay_csv_t *d, replay_warnings_t *w)
{
    if (d->note[0] != '\0') {
        replay_warn(w, "unknown_columns", "columns not read:%s", d->note);
    }
    if (d->sep == ';' || d->sep == '\t') {
        replay_warn(w, "separator",
                    "the header has no comma: the dump is read as %s-separated (a decimal comma is not "
                    "accepted: 1.5, not 1,5)",
                    d->sep == ';' ? "';'" : "tab");
    }
}

/* Finite values of column c: count, min, max. */
static size_t col_range(const double *c, size_t n, double *lo, double *hi)
{
    size_t i, k = 0u;
    *lo = INFINITY;
    *hi = -INFINITY;
    for (i = 0u; c != NULL && i < n; ++i) {
        if (isfinite(c[i])) {
            *lo = fmin(*lo, c[i]);
            *hi = fmax(*hi, c[i]);
            k++;
        }
    }
    return k;
}

void replay_check_ref_units(const magcal_replay_csv_t *d, replay_warnings_t *w)
{
    double lo, hi;
    size_t k = col_range(d->col[MAGCAL_REPLAY_COL_HEADING_REF], d->n_rows, &lo, &hi);
    if (k >= 10u && lo >= -2.0 * k_pi - 1e-6 && hi <= 2.0 * k_pi + 1e-6 && hi - lo > 1.0) {
        replay_warn(w, "ref_radians",
                    "heading_ref_deg: all %lu reference headings lie in [%.4g, %.4g], inside [0, 2 pi]: "
                    "radians? The column is degrees clockwise from north (multiply it by 57.2958)",
                    (unsigned long)k, lo, hi);
    }
}

void replay_check_ins_angles(const magcal_replay_csv_t *d, replay_warnings_t *w)
{
    double lo, hi, rlo, rhi, plo, phi;
    size_t k = col_range(d->col[MAGCAL_REPLAY_COL_YAW], d->n_rows, &lo, &hi);
    (void)col_range(d->col[MAGCAL_REPLAY_COL_ROLL], d->n_rows, &rlo, &rhi);
    (void)col_range(d->col[MAGCAL_REPLAY_COL_PITCH], d->n_rows, &plo, &phi);
    if (k >= 10u && lo >= -2.0 * k_pi - 1e-6 && hi <= 2.0 * k_pi + 1e-6 && hi - lo > 1.0) {
        replay_warn(w, "ins_radians",
                    "yaw_deg spans [%.4g, %.4g] (roll_deg [%.3g, %.3g], pitch_deg [%.3g, %.3g]), inside "
                    "+/- pi: radians? roll_deg, pitch_deg and yaw_deg are degrees (multiply them by 57.2958)",
                    lo, hi, rlo, rhi, plo, phi);
    }
}

/* Accelerometer of row i in the library frame, dump unit; 0 when a cell is missing. */
static int accel_row(const magcal_replay_csv_t *d, const magcal_replay_plane_t *plane, size_t i, double a[3])
{
    unsigned k;
    for (k = 0u; k < 3u; ++k) {
        const double *c = d->col[MAGCAL_REPLAY_COL_AX + plane->src[k]];
        a[k] = (c != NULL) ? c[i] : NAN;
        if (!isfinite(a[k])) {
            return 0;
        }
    }
    return 1;
}

int replay_check_vehicle(const magcal_replay_csv_t *d, const magcal_replay_plane_t *plane, double *share,
                         double *excess_ratio)
{
    double *ratio, *rest, a[3], base;
    size_t i, k = 0u, kr = 0u, total = 0u;
    int vehicle = 0;
    *share = 0.0;
    *excess_ratio = NAN;
    if (d->col[MAGCAL_REPLAY_COL_AX] == NULL || d->col[MAGCAL_REPLAY_COL_AY] == NULL ||
        d->col[MAGCAL_REPLAY_COL_AZ] == NULL) {
        return 0;
    }
    ratio = (double *)malloc(d->n_rows * sizeof(double));
    rest = (double *)malloc(d->n_rows * sizeof(double));
    if (ratio == NULL || rest == NULL) {
        free(ratio);
        free(rest);
        return 0;
    }
    /* the norm of the nearly level rows is the sensor's 1 g (absorbs a scale error) */
    for (i = 0u; i < d->n_rows; ++i) {
        if (accel_row(d, plane, i, a)) {
            double h = sqrt(a[0] * a[0] + a[1] * a[1]);
            double norm = sqrt(h * h + a[2] * a[2]);
            total++;
            if (h < 0.05 * norm) {
                rest[kr++] = norm;
            }
        }
    }
    base = median(rest, kr);
    if (kr < 10u || !(base > 0.0)) {
        free(ratio);
        free(rest);
        return 0;
    }
    for (i = 0u; i < d->n_rows; ++i) {
        if (accel_row(d, plane, i, a)) {
            double h = sqrt(a[0] * a[0] + a[1] * a[1]) / base;
            double norm = sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]) / base;
            if (h > 0.15 && h < 1.0) {
                /* static tilt: norm 1; level road + centripetal h: norm sqrt(1 + h^2) */
                ratio[k++] = (norm - 1.0) / (sqrt(1.0 + h * h) - 1.0);
            }
        }
    }
    if (total > 0u) {
        *share = (double)k / (double)total;
    }
    if (k >= 10u && *share >= 0.05) {
        *excess_ratio = median(ratio, k);
        vehicle = *excess_ratio >= 0.5;
    }
    free(ratio);
    free(rest);
    return vehicle;
}

void replay_check_accel_down(const magcal_replay_csv_t *d, const magcal_replay_plane_t *plane,
                             replay_warnings_t *w)
{
    double *z = (double *)malloc(d->n_rows * sizeof(double)), a[3], med;
    size_t i, k = 0u;
    if (z == NULL) {
        return;
    }
    for (i = 0u; i < d->n_rows; ++i) {
        if (accel_row(d, plane, i, a)) {
            double norm = sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
            if (norm > 0.0) {
                z[k++] = a[2] / norm;
            }
        }
    }
    med = median(z, k);
    free(z);
    if (k > 0u && med < -0.5) {
        replay_warn(w, "accel_down",
                    "the accelerometer's z points down: median az = %.3g |a|, but a level sensor at rest reads "
                    "+1 g on z (body frame x right, y forward, z up; tilt.h). The accelerometer is in a z-down "
                    "(NED) frame or mounted upside down: negate az (and map x, y to right, forward), or --no-tilt",
                    med);
    }
}

void replay_check_eps(const magcal_vec3_t *m, size_t n, int three_d, double eps, const char *unit,
                      replay_warnings_t *w)
{
    double c[3] = {0.0, 0.0, 0.0}, *dist, scale;
    size_t i;
    if (!isfinite(eps) || n < 5u) {
        return;
    }
    dist = (double *)malloc(n * sizeof(double));
    if (dist == NULL) {
        return;
    }
    for (i = 0u; i < n; ++i) {
        c[0] += (double)m[i].x / (double)n;
        c[1] += (double)m[i].y / (double)n;
        c[2] += three_d ? (double)m[i].z / (double)n : 0.0;
    }
    for (i = 0u; i < n; ++i) {
        double dx = (double)m[i].x - c[0], dy = (double)m[i].y - c[1];
        double dz = three_d ? (double)m[i].z - c[2] : 0.0;
        dist[i] = sqrt(dx * dx + dy * dy + dz * dz);
    }
    scale = median(dist, n);
    free(dist);
    if (scale > 0.0 && (eps < 1e-3 * scale || eps > scale)) {
        replay_warn(w, "eps_scale",
                    "--eps %g is %.3g x the data's scale (median distance %.4g %s of the calibration samples "
                    "from their mean): eps is in the dump's own unit (was it tuned on data in another unit, "
                    "e.g. gauss against raw counts?); a useful eps is a small fraction of that distance, or "
                    "leave --eps out for the automatic one",
                    eps, eps / scale, scale, unit != NULL ? unit : "dump units");
    }
}

void replay_check_field_wmm(const magcal_vec3_t *m, const double *b_ned3, size_t first, size_t end,
                            double unit_per_nt, const char *unit, const char *model, replay_warnings_t *w)
{
    static const char *const k_names[3] = {"uT", "nT", "gauss"};
    static const double k_per_nt[3] = {1e-3, 1.0, 1e-5};
    double *v = (double *)malloc((end - first + 1u) * sizeof(double)), *b;
    double mm, bb, ratio, best_r = NAN;
    size_t i, k = 0u, kb = 0u, u, best = 3u;
    if (v == NULL || end <= first) {
        free(v);
        return;
    }
    b = (double *)malloc((end - first + 1u) * sizeof(double));
    if (b == NULL) {
        free(v);
        return;
    }
    for (i = first; i < end; ++i) {
        const double *q = b_ned3 + 3u * i;
        double x = (double)m[i].x, y = (double)m[i].y, z = (double)m[i].z;
        if (isfinite(x) && isfinite(y) && isfinite(z)) {
            v[k++] = sqrt(x * x + y * y + z * z);
        }
        if (isfinite(q[0]) && isfinite(q[1]) && isfinite(q[2])) {
            b[kb++] = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2]);
        }
    }
    mm = median(v, k);
    bb = median(b, kb);
    free(v);
    free(b);
    if (!(mm > 0.0) || !(bb > 0.0)) {
        return;
    }
    ratio = mm / bb;
    if (ratio >= 1.0 / 3.0 && ratio <= 3.0) {
        return;
    }
    for (u = 0u; u < 3u; ++u) { /* the unit whose WMM magnitude is nearest the data's */
        double ru = mm / (bb / unit_per_nt * k_per_nt[u]);
        if (best == 3u || fabs(log(ru)) < fabs(log(best_r))) {
            best = u;
            best_r = ru;
        }
    }
    if (best < 3u && best_r >= 1.0 / 3.0 && best_r <= 3.0 && k_per_nt[best] != unit_per_nt) {
        replay_warn(w, "field_unit",
                    "the field magnitude (median |m| = %.4g %s) is %.3g x the %s intensity at the dump's "
                    "position and date (%.4g %s): wrong unit? With --field-unit %s it is %.2f x",
                    mm, unit, ratio, model, bb, unit, k_names[best], best_r);
    } else {
        replay_warn(w, "field_unit",
                    "the field magnitude (median |m| = %.4g %s) is %.3g x the %s intensity at the dump's "
                    "position and date (%.4g %s): wrong unit (--field-unit uT|nT|gauss), a scaled sensor, or "
                    "a large hard iron",
                    mm, unit, ratio, model, bb, unit);
    }
}

void replay_check_level(const magcal_replay_csv_t *d, const magcal_vec3_t *fed, const magcal_replay_plane_t *plane,
                        int vehicle, const replay_report_t *r, replay_warnings_t *w)
{
    const double *cz = d->col[MAGCAL_REPLAY_COL_MX + plane->src[2]];
    size_t n = r->cal_end - r->cal_first, i, k = 0u, kt = 0u;
    double *v = (double *)malloc((n + 1u) * sizeof(double));
    double cx = 0.0, cy = 0.0, rxy = NAN, zrel = NAN, tilt90 = NAN, a[3];
    char why[200];
    if (v == NULL || n < 10u) {
        free(v);
        return;
    }
    why[0] = '\0';
    /* horizontal scale: median distance from the mean in the plane */
    for (i = r->cal_first; i < r->cal_end; ++i) {
        cx += (double)fed[i].x / (double)n;
        cy += (double)fed[i].y / (double)n;
    }
    for (i = r->cal_first; i < r->cal_end; ++i) {
        v[k++] = hypot((double)fed[i].x - cx, (double)fed[i].y - cy);
    }
    rxy = median(v, k);
    if (cz != NULL && rxy > 0.0) {
        /* the out-of-plane axis of a level turn is nearly constant: its 5..95 % range */
        double lo, hi;
        k = 0u;
        for (i = r->cal_first; i < r->cal_end; ++i) {
            if (isfinite(cz[i])) {
                v[k++] = (double)fed[i].z;
            }
        }
        if (k >= 10u) {
            lo = quantile(v, k, 0.05);
            hi = quantile(v, k, 0.95);
            zrel = 0.5 * (hi - lo) / rxy;
        }
    }
    if (!vehicle) {
        for (i = r->cal_first; i < r->cal_end; ++i) {
            if (accel_row(d, plane, i, a)) {
                v[kt++] = atan2(hypot(a[0], a[1]), fabs(a[2])) * k_deg;
            }
        }
        tilt90 = (kt >= 10u) ? quantile(v, kt, 0.9) : NAN;
    }
    free(v);
    if (isfinite(zrel) && zrel > 0.25) {
        (void)snprintf(why, sizeof why, "the out-of-plane axis varies by +/-%.0f %% of the in-plane radius "
                                         "(a level turn keeps it nearly constant)", 100.0 * zrel);
    } else if (isfinite(tilt90) && tilt90 > 20.0) {
        (void)snprintf(why, sizeof why, "the accelerometer shows a tilt above %.0f deg on 10 %% of the "
                                         "calibration rows", tilt90);
    } else if (r->have_geometry && r->spread_corrected > 0.08 && !(r->fit != NULL && strcmp(r->fit, "plain") == 0)) {
        /* (not after the plain fit: its outliers alone leave such a spread) */
        (void)snprintf(why, sizeof why, "the corrected radius still varies by %.1f %% (std/mean): the samples "
                                         "fill the ellipse instead of lying on it, as a 3-D motion projected on "
                                         "the plane does", 100.0 * r->spread_corrected);
    } else if (!r->have_geometry && strcmp(r->status, "residual") == 0) {
        (void)snprintf(why, sizeof why, "the fit residual is too large for a level turn");
    }
    if (why[0] != '\0') {
        replay_warn(w, "not_level",
                    "the dump does not look level: %s. A 2-D calibration needs level turns; try --mode 3d%s",
                    why, cz == NULL ? " (needs the third field axis)" : "");
    }
}

void replay_check_heading_pattern(const double *hdg_deg, const double *ref_deg, size_t n_rows,
                                  const replay_report_t *r, double spread_ratio, replay_warnings_t *w)
{
    double ec = 0.0, es = 0.0, sc = 0.0, ss = 0.0, re, rs, me, ms;
    size_t i, k = 0u;
    int accel_down = 0;
    if (ref_deg == NULL || !(r->heading_rms_deg > 10.0) || !(spread_ratio >= 2.0)) {
        return;
    }
    for (i = 0u; i < n_rows; ++i) {
        if ((i >= r->cal_first && i < r->cal_end) || (i >= r->ref_first && i < r->ref_end) ||
            !isfinite(hdg_deg[i]) || !isfinite(ref_deg[i])) {
            continue;
        }
        ec += cos((hdg_deg[i] - ref_deg[i]) / k_deg);
        es += sin((hdg_deg[i] - ref_deg[i]) / k_deg);
        sc += cos((hdg_deg[i] + ref_deg[i]) / k_deg);
        ss += sin((hdg_deg[i] + ref_deg[i]) / k_deg);
        k++;
    }
    if (k < 10u) {
        return;
    }
    re = hypot(ec, es) / (double)k; /* 1: the error is one constant */
    rs = hypot(sc, ss) / (double)k; /* 1: heading + reference is one constant (mirror) */
    me = atan2(es, ec) * k_deg;
    ms = fmod(atan2(ss, sc) * k_deg + 360.0, 360.0);
    for (i = 0u; i < w->n; ++i) {
        accel_down = accel_down || strcmp(w->w[i].id, "accel_down") == 0;
    }
    if (rs > 0.9 && rs > re) {
        replay_warn(w, "mirrored",
                    "heading RMS %.1f deg against the reference with a good fit (radius spread %.1fx smaller): "
                    "the heading turns the wrong way (heading + reference = %.0f deg on every row): %s",
                    r->heading_rms_deg, spread_ratio, ms,
                    accel_down ? "the z-down accelerometer (warning accel_down) mirrors the tilt-compensated "
                                 "heading: fix its sign first (or --no-tilt)"
                               : "the axes are swapped or in another frame (a NED sensor frame is x forward, y "
                                 "right, z down; magcal wants x right, y forward, z up): try --plane YX (then "
                                 "--ref-rows for a remaining rotation)");
    } else if (re > 0.9 && fabs(me) > 10.0) {
        replay_warn(w, "heading_bias",
                    "heading RMS %.1f deg against the reference with a good fit (radius spread %.1fx smaller) "
                    "and a constant bias of %+.1f deg: a wrong --declination (the reference is a true heading), a "
                    "rotated mounting or a wrong frame (%s); fit a compass swing with --ref-rows, or check the "
                    "axes (--plane YX if x and y are swapped%s)",
                    r->heading_rms_deg, spread_ratio, me,
                    fabs(fabs(me) - 180.0) < 20.0 ? "180 deg: x and y both negated?"
                    : fabs(fabs(me) - 90.0) < 20.0 ? "90 deg: an axis swapped and one negated?"
                                                   : "a rotated sensor",
                    fabs(fabs(me) - 90.0) < 20.0 ? ", then negate one of them" : "");
    }
}

void replay_check_field_range(double magnitude, int horizontal, const char *unit, replay_warnings_t *w)
{
    /* Earth's field: 22..67 uT in total (WMM), its horizontal part 0..42 uT; the bounds leave room
     * for a distorted installation, not for a wrong unit (x100, x1000) */
    double ut, lo = horizontal ? 0.5 : 10.0, hi = 100.0;
    if (unit == NULL || !isfinite(magnitude)) {
        return;
    }
    ut = (strcmp(unit, "nT") == 0) ? magnitude * 1e-3 : (strcmp(unit, "gauss") == 0) ? magnitude * 100.0 : magnitude;
    if (ut < lo || ut > hi) {
        replay_warn(w, "field_range",
                    "the calibrated %s is %.4g %s = %.4g uT, outside the %.3g..%.3g uT a magnetometer sees of "
                    "the Earth's field (%s): is --field-unit %s right?",
                    horizontal ? "radius (horizontal field)" : "field magnitude", magnitude, unit, ut, lo, hi,
                    horizontal ? "its horizontal part is 0..42 uT" : "22..67 uT", unit);
    }
}
