/* magcal-replay: 3-D, aided and swing modes (see replay_modes.h). */
#include "replay_modes.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cjson/cJSON.h>

#include "magcal/aided.h"
#include "magcal/geomag.h"
#include "magcal/optics.h"
#include "replay_cal.h"

/* magcal_ellipsoid_fit's fixed scratch (the workspace-free fit: no per-sample storage) */
static magcal_ellipsoid_fit_scratch_t g_fit_scratch;

static const double k_pi = 3.14159265358979323846;

static double wrap180d(double a)
{
    a = fmod(a + 180.0, 360.0);
    if (a < 0.0) {
        a += 360.0;
    }
    return a - 180.0;
}

static double wrap360d(double a)
{
    a = fmod(a, 360.0);
    if (a < 0.0) {
        a += 360.0;
    }
    return (a >= 360.0) ? 0.0 : a;
}

/* ------------------------------------------------------------------ 3-D */

static const char *model_name(magcal_ellipsoid_model_t m)
{
    switch (m) {
    case MAGCAL_ELLIPSOID_MODEL_QUADRIC9: return "quadric9";
    case MAGCAL_ELLIPSOID_MODEL_QUADRIC10: return "quadric10";
    case MAGCAL_ELLIPSOID_MODEL_SPHERE: return "sphere";
    default: return "auto";
    }
}

int replay_classify_3d(const magcal_ellipsoid_result_t *fit, const magcal_vec3_t *m)
{
    uint8_t f = 0u;
    size_t cnt = 0u;
    if (magcal_ellipsoid_outliers(fit, m, 1u, &f, &cnt) != MAGCAL_OK) {
        return 0;
    }
    return f != 0u;
}

/* OPTICS density stage on the 3-D samples: inlier[0..n) (1 = kept). Returns REPLAY_EXIT_OK,
 * _CAL_FAILED (no cluster, degenerate data: status and reason set) or _INTERNAL. */
static int density_3d(const magcal_vec3_t *m, size_t n, const char *filter, double eps, long min_pts,
                      replay_report_t *r, uint8_t *inlier)
{
    magcal_optics_cfg_t cfg = MAGCAL_OPTICS_CFG_DEFAULT;
    magcal_optics_result_t info;
    magcal_status_t st;
    size_t wlen = MAGCAL_OPTICS3_FILTER_WORKSPACE_LEN(n);
    uint32_t *work;

    if (strcmp(filter, "optics-classic") == 0) {
        cfg.order = MAGCAL_OPTICS_CLASSIC;
    }
    if (isfinite(eps) && eps > 0.0) {
        cfg.eps = (float)eps;
        cfg.eps_prime = (float)eps;
        cfg.min_pts = 4u;
    }
    if (min_pts > 0) {
        if (min_pts > (long)MAGCAL_MAX_MIN_PTS) {
            fprintf(stderr, "magcal-replay: --min-pts %ld is above MAGCAL_MAX_MIN_PTS (%u)\n", min_pts,
                    (unsigned)MAGCAL_MAX_MIN_PTS);
            return REPLAY_EXIT_USAGE;
        }
        cfg.min_pts = (uint16_t)min_pts;
    }
    work = (uint32_t *)malloc(wlen + 4u);
    if (work == NULL) {
        fprintf(stderr, "magcal-replay: out of memory\n");
        return REPLAY_EXIT_INTERNAL;
    }
    st = magcal_optics_filter3(&cfg, m, n, work, wlen, inlier, &info);
    free(work);
    if (st != MAGCAL_OK) {
        r->status = replay_status_id(st);
        r->status_code = (int)st;
        (void)snprintf(r->reason, sizeof r->reason, "3-D OPTICS density stage: %s on %lu samples",
                       magcal_status_str(st), (unsigned long)n);
        r->have_3d = 0;
        return (st == MAGCAL_ERR_NULL || st == MAGCAL_ERR_WORKSPACE) ? REPLAY_EXIT_INTERNAL
                                                                      : REPLAY_EXIT_CAL_FAILED;
    }
    r->eps3 = info.eps;
    r->eps_prime3 = info.eps_prime;
    r->min_pts3 = (long)info.min_pts;
    return REPLAY_EXIT_OK;
}

/* More rows than one density run takes (MAGCAL_MAX_SAMPLES): the stage runs on `stride`
 * interleaved subsets (rows k, k + stride, ...), each a thinner copy of the whole trajectory, so
 * every row is judged; the reported eps/MinPts are those of the last subset. sub: n bytes. */
static int density_3d_interleaved(const magcal_vec3_t *m, size_t n, const char *filter, double eps,
                                  long min_pts, replay_report_t *r, uint8_t *inlier, uint8_t *sub)
{
    const size_t stride = (n + MAGCAL_MAX_SAMPLES - 1u) / MAGCAL_MAX_SAMPLES;
    magcal_vec3_t *part = (magcal_vec3_t *)malloc((n / stride + 1u) * sizeof *part);
    size_t k, i, np;
    int rc = REPLAY_EXIT_OK;
    if (part == NULL) {
        fprintf(stderr, "magcal-replay: out of memory\n");
        return REPLAY_EXIT_INTERNAL;
    }
    fprintf(stderr, "magcal-replay: note: %lu calibration samples exceed MAGCAL_MAX_SAMPLES (%u): "
                    "3-D density stage run on %lu interleaved subsets (every %lu-th row)\n",
            (unsigned long)n, (unsigned)MAGCAL_MAX_SAMPLES, (unsigned long)stride,
            (unsigned long)stride);
    for (k = 0u; k < stride && rc == REPLAY_EXIT_OK; ++k) {
        for (np = 0u, i = k; i < n; i += stride) {
            part[np++] = m[i];
        }
        rc = density_3d(part, np, filter, eps, min_pts, r, sub);
        for (np = 0u, i = k; rc == REPLAY_EXIT_OK && i < n; i += stride) {
            inlier[i] = sub[np++];
        }
    }
    free(part);
    return rc;
}

/* issue 14: the library's pre-test (magcal_ellipsoid_calibrate): with the default density stage,
 * the fit of all samples is kept (*pre, returns 1) and the density stage skipped when it is OK and
 * no sample lies pretest_max_rel x F off its shell; 0: run the density stage as before. */
static int pretest_3d(const magcal_vec3_t *m, size_t n, magcal_ellipsoid_result_t *pre)
{
    magcal_ellipsoid_calibrate_cfg_t pc = MAGCAL_ELLIPSOID_CALIBRATE_CFG_DEFAULT;
    magcal_ellipsoid_calibrate_info_t info;
    size_t wlen = MAGCAL_ELLIPSOID_CALIBRATE_WORKSPACE_LEN(n);
    uint32_t *work = (uint32_t *)malloc(wlen + 4u);
    int clean;
    if (work == NULL) {
        return 0;
    }
    pc.mode = MAGCAL_ELLIPSOID_DENSITY_NEVER; /* the pre-test alone; AUTO's rule applied below */
    clean = magcal_ellipsoid_calibrate(&pc, m, n, work, wlen, NULL, pre, &info) == MAGCAL_OK &&
            info.pretest_max_rel <= pc.pretest_max_rel;
    free(work);
    return clean;
}

int replay_fit_3d(const magcal_vec3_t *m, size_t n, const char *filter, double eps, long min_pts,
                  replay_report_t *r, magcal_ellipsoid_result_t *fit, unsigned char *flags)
{
    const magcal_ellipsoid_cfg_t cfg = MAGCAL_ELLIPSOID_CFG_DEFAULT;
    magcal_ellipsoid_result_t res;
    magcal_status_t st;
    float cov = 0.0f;
    size_t n_flag = 0u, k3, nk = 0u;
    uint8_t *mask, *inlier;
    magcal_vec3_t *kept;
    int i, j, rc = REPLAY_EXIT_OK, prefit = 0;

    r->eps3 = NAN;
    r->eps_prime3 = NAN;
    r->min_pts3 = 0;
    r->n_density3 = 0u;
    mask = (uint8_t *)malloc(2u * n + 1u);
    kept = (magcal_vec3_t *)malloc((n + 1u) * sizeof *kept);
    if (mask == NULL || kept == NULL) {
        free(mask);
        free(kept);
        fprintf(stderr, "magcal-replay: out of memory\n");
        return REPLAY_EXIT_INTERNAL;
    }
    inlier = mask + n;
    (void)memset(inlier, 1, n);
    if (strcmp(filter, "none") != 0) {
        if (strcmp(filter, "optics") == 0 && !(isfinite(eps) && eps > 0.0) && min_pts <= 0 &&
            pretest_3d(m, n, &res)) {
            r->filter = "optics (skipped: pre-test fit, no sample 0.15 F off the shell)";
            prefit = 1;
        } else if (n > (size_t)MAGCAL_MAX_SAMPLES) {
            rc = density_3d_interleaved(m, n, filter, eps, min_pts, r, inlier, mask);
        } else {
            rc = density_3d(m, n, filter, eps, min_pts, r, inlier);
        }
        if (prefit == 0 && rc != REPLAY_EXIT_OK) {
            free(mask);
            free(kept);
            return rc;
        }
    }
    for (k3 = 0u; k3 < n; ++k3) {
        if (inlier[k3] != 0u) {
            kept[nk++] = m[k3];
        }
    }
    r->n_density3 = n - nk;

    if (prefit == 0) {
        memset(&res, 0, sizeof res);
        st = magcal_ellipsoid_fit(kept, nk, &cfg, &g_fit_scratch, &res);
    } else {
        st = MAGCAL_OK; /* the pre-test's fit of all samples: what magcal_ellipsoid_calibrate returns */
    }
    r->status = replay_status_id(st);
    r->status_code = (int)st;
    if (st != MAGCAL_OK) {
        magcal_vec3_t c = {0.0f, 0.0f, 0.0f};
        size_t k;
        /* coverage around the sample mean, to explain a coverage failure */
        for (k = 0u; k < nk; ++k) {
            c.x += kept[k].x / (float)nk;
            c.y += kept[k].y / (float)nk;
            c.z += kept[k].z / (float)nk;
        }
        if (nk > 0u && magcal_ellipsoid_coverage(kept, nk, &c, &cov) == MAGCAL_OK) {
            r->coverage3 = cov;
        } else {
            r->coverage3 = NAN;
        }
        if (st == MAGCAL_ERR_COVERAGE) {
            (void)snprintf(r->reason, sizeof r->reason,
                           "%s: %lu samples (%lu removed by the density stage); direction coverage about the "
                           "sample mean %.2f of the 72 cells (sphere needs %.2f, quadric %.2f)",
                           magcal_status_str(st), (unsigned long)nk, (unsigned long)r->n_density3, (double)cov,
                           (double)cfg.min_coverage_sphere, (double)cfg.min_coverage_full);
        } else { /* the trust gates' statuses say what to do (ellipsoid.h, docs/calibration_3d.md) */
            (void)snprintf(r->reason, sizeof r->reason, "%s: %lu samples (%lu removed by the density stage)",
                           magcal_status_str(st), (unsigned long)nk, (unsigned long)r->n_density3);
        }
        r->have_3d = 0;
        free(mask);
        free(kept);
        return (st == MAGCAL_ERR_NULL || st == MAGCAL_ERR_ARG) ? REPLAY_EXIT_INTERNAL : REPLAY_EXIT_CAL_FAILED;
    }
    /* per-sample mask of the fit's final gate; on the fit's own input it must count n_rejected */
    st = magcal_ellipsoid_outliers(&res, kept, nk, mask, &n_flag);
    if (st != MAGCAL_OK || n_flag != res.n_rejected) {
        fprintf(stderr, "magcal-replay: magcal_ellipsoid_outliers: %s, %lu flagged vs n_rejected %lu\n",
                magcal_status_str(st), (unsigned long)n_flag, (unsigned long)res.n_rejected);
        free(mask);
        free(kept);
        return REPLAY_EXIT_INTERNAL;
    }
    for (k3 = 0u, nk = 0u; k3 < n; ++k3) {
        flags[k3] = (unsigned char)((inlier[k3] == 0u) ? 1u : mask[nk++]);
    }
    free(mask);
    free(kept);
    *fit = res;
    r->have_3d = 1;
    r->model3 = model_name(res.model);
    r->coverage3 = res.coverage;
    r->off3[0] = res.cal.v.x;
    r->off3[1] = res.cal.v.y;
    r->off3[2] = res.cal.v.z;
    for (i = 0; i < 3; ++i) {
        for (j = 0; j < 3; ++j) {
            r->mat3[i][j] = res.cal.g[i][j];
        }
    }
    r->field3 = res.cal.field;
    r->residual_rms = res.residual_rms;
    r->n_used = res.n_used;
    r->n_outliers = res.n_rejected + r->n_density3;
    r->n_rejected3 = res.n_rejected;
    return REPLAY_EXIT_OK;
}

/* ------------------------------------------------------------------ swing */

int replay_swing_fit(const double *psi_c_deg, const double *psi_ref_deg, size_t first, size_t end,
                     int fourier, replay_report_t *r, replay_swing_t *sw)
{
    size_t i, n = 0u, distinct = 0u, np = 0u, g;
    double keys[MAGCAL_SWING_COG_BINS + 1u];
    double off_sum[MAGCAL_SWING_COG_BINS + 1u];
    size_t cnt[MAGCAL_SWING_COG_BINS + 1u];
    float *pc = NULL, *pr = NULL;
    magcal_status_t st;
    int bunched;

    memset(sw, 0, sizeof *sw);
    sw->fourier = fourier;
    r->swing_model = fourier ? "fourier" : "smith";
    r->swing_ncoef = 0u;
    r->swing_fit_rms_deg = NAN;
    r->swing_fit_max_deg = NAN;
    /* reference pairs; distinct reference values (to 0.01 deg), at most COG_BINS + 1 tracked */
    for (i = first; i < end; ++i) {
        double key;
        if (!isfinite(psi_c_deg[i]) || !isfinite(psi_ref_deg[i])) {
            continue;
        }
        n++;
        key = floor(wrap360d(psi_ref_deg[i]) * 100.0 + 0.5) / 100.0;
        for (g = 0u; g < distinct && keys[g] != key; ++g) {
        }
        if (g == distinct && distinct <= MAGCAL_SWING_COG_BINS) {
            keys[distinct] = key;
            off_sum[distinct] = 0.0;
            cnt[distinct] = 0u;
            distinct++;
        }
        if (g < distinct) {
            off_sum[g] += wrap180d(psi_c_deg[i] - key);
            cnt[g]++;
        }
    }
    r->swing_n_ref = n;
    /* reference rows bunched at a few headings (a swing at marked positions): each heading must
     * count once, not by the time spent there */
    bunched = distinct <= MAGCAL_SWING_COG_BINS && n > distinct;
    r->swing_method = bunched ? "bins" : "pairs";

    if (!fourier && bunched) {
        magcal_swing_cog_t acc;
        const magcal_swing_cog_cfg_t cfg = MAGCAL_SWING_COG_CFG_DEFAULT;
        magcal_swing_stats_t stats;
        size_t bins = 0u, legs = 0u;
        st = magcal_swing_cog_init(&acc, &cfg);
        for (i = first; i < end && st == MAGCAL_OK; ++i) {
            if (isfinite(psi_c_deg[i]) && isfinite(psi_ref_deg[i])) {
                st = magcal_swing_cog_add_pair(&acc, (float)psi_c_deg[i], (float)psi_ref_deg[i], 1.0f);
            }
        }
        if (st == MAGCAL_OK) {
            (void)magcal_swing_cog_count(&acc, &bins, &legs);
            r->swing_n_points = bins;
            memset(&stats, 0, sizeof stats);
            st = magcal_swing_cog_fit(&acc, &sw->swing, &stats);
            if (st == MAGCAL_OK) {
                r->swing_fit_rms_deg = stats.rms_deg;
                r->swing_fit_max_deg = stats.max_abs_deg;
            }
        }
    } else {
        /* pairs: every row, or (Fourier on bunched rows) one mean pair per reference heading */
        pc = (float *)calloc(n + 1u, sizeof *pc);
        pr = (float *)calloc(n + 1u, sizeof *pr);
        if (pc == NULL || pr == NULL) {
            free(pc);
            free(pr);
            return REPLAY_EXIT_INTERNAL;
        }
        if (bunched) {
            for (g = 0u; g < distinct; ++g) {
                pc[np] = (float)wrap360d(keys[g] + off_sum[g] / (double)cnt[g]);
                pr[np] = (float)keys[g];
                np++;
            }
        } else if (fourier) {
            /* the adaptive order stops on the max residual at the points: fit per-bin means (10-degree
             * bins of psi_c), as the motion swing does, not every noisy row */
            double bc[MAGCAL_SWING_COG_BINS], bd[MAGCAL_SWING_COG_BINS];
            size_t bn[MAGCAL_SWING_COG_BINS];
            const double w = 360.0 / (double)MAGCAL_SWING_COG_BINS;
            r->swing_method = "bins";
            for (g = 0u; g < MAGCAL_SWING_COG_BINS; ++g) {
                bc[g] = bd[g] = 0.0;
                bn[g] = 0u;
            }
            for (i = first; i < end; ++i) {
                if (isfinite(psi_c_deg[i]) && isfinite(psi_ref_deg[i])) {
                    double pcw = wrap360d(psi_c_deg[i]);
                    g = (size_t)floor(pcw / w) % MAGCAL_SWING_COG_BINS;
                    bc[g] += wrap180d(pcw - ((double)g + 0.5) * w);
                    bd[g] += wrap180d(psi_ref_deg[i] - pcw);
                    bn[g]++;
                }
            }
            for (g = 0u; g < MAGCAL_SWING_COG_BINS; ++g) {
                if (bn[g] > 0u) {
                    double c0 = ((double)g + 0.5) * w + bc[g] / (double)bn[g];
                    pc[np] = (float)wrap360d(c0);
                    pr[np] = (float)wrap360d(c0 + bd[g] / (double)bn[g]);
                    np++;
                }
            }
        } else {
            for (i = first; i < end; ++i) {
                if (isfinite(psi_c_deg[i]) && isfinite(psi_ref_deg[i])) {
                    pc[np] = (float)psi_c_deg[i];
                    pr[np] = (float)psi_ref_deg[i];
                    np++;
                }
            }
        }
        r->swing_n_points = np;
        if (!fourier) {
            const magcal_swing_cfg_t cfg = MAGCAL_SWING_CFG_DEFAULT;
            magcal_swing_stats_t stats;
            memset(&stats, 0, sizeof stats);
            st = (np < MAGCAL_SWING_MIN_POINTS)
                     ? MAGCAL_ERR_TOO_FEW_POINTS
                     : magcal_swing_fit(&cfg, pc, pr, NULL, np, MAGCAL_SWING_REG_MEASURED, &sw->swing, &stats);
            if (st == MAGCAL_OK) {
                r->swing_fit_rms_deg = stats.rms_deg;
                r->swing_fit_max_deg = stats.max_abs_deg;
            }
        } else {
            const magcal_errmodel_cfg_t cfg = MAGCAL_ERRMODEL_CFG_DEFAULT;
            static MAGCAL_ERRMODEL_WORKSPACE_DECLARE(em_work);
            magcal_errmodel_stats_t stats;
            memset(&stats, 0, sizeof stats);
            st = (np < 3u) ? MAGCAL_ERR_TOO_FEW_POINTS : magcal_errmodel_fit(&cfg, pc, pr, np, em_work, sizeof em_work, &sw->fmodel, &stats);
            if (st == MAGCAL_OK || st == MAGCAL_ERR_THRESHOLD) {
                r->swing_fit_rms_deg = stats.rms_deg;
                r->swing_fit_max_deg = stats.max_abs_deg;
                r->swing_order = stats.order;
            }
        }
        free(pc);
        free(pr);
    }
    r->swing_status = replay_status_id(st);
    r->swing_status_code = (int)st;
    if (st != MAGCAL_OK) {
        return REPLAY_EXIT_OK; /* reported, the calibration itself stands */
    }
    sw->ok = 1;
    if (!fourier) {
        r->swing_ncoef = MAGCAL_SWING_NCOEF;
        for (g = 0u; g < MAGCAL_SWING_NCOEF; ++g) {
            r->swing_coef[g] = sw->swing.coef_deg[g];
        }
    } else {
        r->swing_order = sw->fmodel.order;
        r->swing_ncoef = 2u * (size_t)sw->fmodel.order + 1u;
        for (g = 0u; g < r->swing_ncoef && g < REPLAY_MAX_SWING_COEF; ++g) {
            r->swing_coef[g] = sw->fmodel.coef[g];
        }
    }
    return REPLAY_EXIT_OK;
}

double replay_swing_apply(const replay_swing_t *sw, double psi_c_deg)
{
    float out = 0.0f;
    magcal_status_t st;
    if (!sw->ok || !isfinite(psi_c_deg)) {
        return NAN;
    }
    st = sw->fourier ? magcal_errmodel_apply(&sw->fmodel, (float)psi_c_deg, &out)
                     : magcal_swing_apply(&sw->swing, (float)psi_c_deg, &out);
    return (st == MAGCAL_OK) ? wrap360d((double)out) : NAN;
}

/* ------------------------------------------------------------------ aided */

/* Days since 1970-01-01 of a Gregorian date (H. Hinnant's days_from_civil). */
static long days_from_civil(long y, long m, long dd)
{
    long era, yoe, doy, doe;
    y -= (m <= 2) ? 1 : 0;
    era = (y >= 0 ? y : y - 399) / 400;
    yoe = y - era * 400;
    doy = (153 * (m + (m > 2 ? -3 : 9)) + 2) / 5 + dd - 1;
    doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    return era * 146097 + doe - 719468;
}

/* Decimal year of a Unix time (UTC): year + (t - start of year) / length of year. */
static double unix_to_year(double t)
{
    long day = (long)floor(t / 86400.0);
    long y = 1970 + (long)floor((double)day / 365.2425);
    double y0, y1;
    while (days_from_civil(y, 1, 1) > day) {
        --y;
    }
    while (days_from_civil(y + 1, 1, 1) <= day) {
        ++y;
    }
    y0 = 86400.0 * (double)days_from_civil(y, 1, 1);
    y1 = 86400.0 * (double)days_from_civil(y + 1, 1, 1);
    return (double)y + (t - y0) / (y1 - y0);
}

int replay_wmm_rows(const magcal_replay_csv_t *d, const replay_aided_opts_t *o, double *b_ned3,
                    double *decl_deg, char *err, size_t err_len)
{
    const double *lat = d->col[MAGCAL_REPLAY_COL_LAT], *lon = d->col[MAGCAL_REPLAY_COL_LON];
    const double *hgt = d->col[MAGCAL_REPLAY_COL_HEIGHT], *yr = d->col[MAGCAL_REPLAY_COL_YEAR];
    const double *t = d->col[MAGCAL_REPLAY_COL_T];
    double last[4] = {NAN, NAN, NAN, NAN};
    magcal_geomag_result_t f;
    magcal_status_t st = MAGCAL_ERR_ARG;
    size_t i;
    if (!isfinite(o->year) && yr == NULL && t == NULL) {
        (void)snprintf(err, err_len, "no epoch: the dump has neither decimal_year nor t (Unix time); give --year");
        return REPLAY_EXIT_INPUT;
    }
    memset(&f, 0, sizeof f);
    for (i = 0u; i < d->n_rows; ++i) {
        double y = isfinite(o->year) ? o->year : (yr != NULL) ? yr[i] : NAN;
        if (!isfinite(o->year) && yr == NULL) {
            if (isfinite(t[i]) && t[i] < 946684800.0) {
                (void)snprintf(err, err_len,
                               "row %lu: t = %g is not a Unix time (before 2000); add decimal_year or give --year",
                               (unsigned long)i, t[i]);
                return REPLAY_EXIT_INPUT;
            }
            y = isfinite(t[i]) ? unix_to_year(t[i]) : NAN;
        }
        b_ned3[3u * i] = b_ned3[3u * i + 1u] = b_ned3[3u * i + 2u] = NAN;
        decl_deg[i] = NAN;
        if (!isfinite(lat[i]) || !isfinite(lon[i]) || !isfinite(hgt[i]) || !isfinite(y)) {
            continue;
        }
        /* the model is evaluated again only when the position or date moves (a fixed site: once);
         * thresholds ~1 m and ~1 h change the field by far less than 1 nT */
        if (!(fabs(lat[i] - last[0]) < 1e-5 && fabs(lon[i] - last[1]) < 1e-5 && fabs(hgt[i] - last[2]) < 1e-3 &&
              fabs(y - last[3]) < 1e-4)) {
            st = magcal_geomag_eval(o->igrf ? &magcal_geomag_igrf14 : &magcal_geomag_wmm2025, (float)lat[i],
                                    (float)lon[i], (float)hgt[i], (float)y, &f);
            last[0] = lat[i];
            last[1] = lon[i];
            last[2] = hgt[i];
            last[3] = y;
            if (st == MAGCAL_ERR_OUT_OF_VALIDITY) {
                (void)snprintf(err, err_len, "row %lu: epoch %.4f outside %s validity (%s)", (unsigned long)i, y,
                               o->igrf ? "IGRF-14" : "WMM2025", o->igrf ? "1900.0-2030.0" : "2025.0-2030.0; --model igrf14 covers 1900-2030");
                return REPLAY_EXIT_INPUT;
            }
            if (st != MAGCAL_OK) {
                (void)snprintf(err, err_len, "row %lu: %s rejects lat %g lon %g height %g km: %s", (unsigned long)i,
                               o->igrf ? "IGRF-14" : "WMM2025", lat[i], lon[i], hgt[i], magcal_status_str(st));
                return REPLAY_EXIT_INPUT;
            }
        }
        b_ned3[3u * i] = (double)f.x_nt * o->unit_per_nt;
        b_ned3[3u * i + 1u] = (double)f.y_nt * o->unit_per_nt;
        b_ned3[3u * i + 2u] = (double)f.z_nt * o->unit_per_nt;
        decl_deg[i] = f.decl_deg;
    }
    return REPLAY_EXIT_OK;
}

const char *replay_gate_name(unsigned char g)
{
    switch (g) {
    case MAGCAL_AIDED_GATE_NONE: return "none";
    case MAGCAL_AIDED_GATE_DOP: return "dop";
    case MAGCAL_AIDED_GATE_RAW: return "raw";
    case MAGCAL_AIDED_GATE_FIELD: return "field";
    case MAGCAL_AIDED_GATE_VECTOR: return "vector";
    case REPLAY_GATE_SKIPPED: return "skipped";
    default: return "";
    }
}

static double unit_per_nt_of(const char *u)
{
    if (strcmp(u, "uT") == 0) {
        return 1e-3;
    }
    if (strcmp(u, "nT") == 0) {
        return 1.0;
    }
    if (strcmp(u, "gauss") == 0) {
        return 1e-5;
    }
    return NAN;
}

/* n finite numbers of a JSON array; 0 ok, -1 otherwise */
static int json_numbers(const cJSON *arr, double *out, int n)
{
    int k;
    if (!cJSON_IsArray(arr) || cJSON_GetArraySize(arr) != n) {
        return -1;
    }
    for (k = 0; k < n; ++k) {
        const cJSON *it = cJSON_GetArrayItem(arr, k);
        if (!cJSON_IsNumber(it) || !isfinite(it->valuedouble)) {
            return -1;
        }
        out[k] = it->valuedouble;
    }
    return 0;
}

int replay_read_prior(const char *path, double unit_per_nt, double field_ref, magcal_ellipsoid_cal_t *prior,
                      double *g_scale, char *err, size_t err_len)
{
    FILE *f = fopen(path, "rb");
    char *text = NULL;
    long len;
    cJSON *root = NULL;
    const cJSON *mat, *off, *unit, *mode, *field;
    double g[3][3], v[3], det, scale = 1.0, gnorm = 0.0, gs = 1.0;
    int i, j, rc = REPLAY_EXIT_INPUT;

    if (f == NULL) {
        (void)snprintf(err, err_len, "%s: cannot open the prior: %s", path, strerror(errno));
        return REPLAY_EXIT_INPUT;
    }
    if (fseek(f, 0, SEEK_END) != 0 || (len = ftell(f)) < 0 || len > (1L << 20) || fseek(f, 0, SEEK_SET) != 0) {
        (void)snprintf(err, err_len, "%s: prior unreadable or larger than 1 MiB", path);
        fclose(f);
        return REPLAY_EXIT_INPUT;
    }
    text = (char *)malloc((size_t)len + 1u);
    if (text == NULL || fread(text, 1u, (size_t)len, f) != (size_t)len) {
        (void)snprintf(err, err_len, "%s: cannot read the prior", path);
        goto out;
    }
    text[len] = '\0';
    root = cJSON_Parse(text);
    if (root == NULL || !cJSON_IsObject(root)) {
        (void)snprintf(err, err_len, "%s: prior is not a JSON object (a magcal-replay --json report of --mode 3d "
                       "or aided, or {\"matrix\": [[..],[..],[..]], \"offset\": [x, y, z]})", path);
        goto out;
    }
    mat = cJSON_GetObjectItemCaseSensitive(root, "matrix");
    off = cJSON_GetObjectItemCaseSensitive(root, "offset");
    if (mat == NULL || off == NULL) {
        (void)snprintf(err, err_len, "%s: prior has no \"%s\" key (needs \"matrix\": 3x3 G and \"offset\": V, "
                       "as in a --mode 3d or aided JSON report)", path, mat == NULL ? "matrix" : "offset");
        goto out;
    }
    if (!cJSON_IsArray(mat) || cJSON_GetArraySize(mat) != 3) {
        (void)snprintf(err, err_len, "%s: prior \"matrix\" must be 3 rows of 3 finite numbers", path);
        goto out;
    }
    for (i = 0; i < 3; ++i) {
        if (json_numbers(cJSON_GetArrayItem(mat, i), g[i], 3) != 0) {
            (void)snprintf(err, err_len, "%s: prior \"matrix\" must be 3 rows of 3 finite numbers", path);
            goto out;
        }
    }
    if (json_numbers(off, v, 3) != 0) {
        (void)snprintf(err, err_len, "%s: prior \"offset\" must be 3 finite numbers", path);
        goto out;
    }
    /* unit of the file, when it says: top level, else the aided object's */
    unit = cJSON_GetObjectItemCaseSensitive(root, "field_unit");
    if (unit == NULL) {
        const cJSON *ad = cJSON_GetObjectItemCaseSensitive(root, "aided");
        unit = (ad != NULL) ? cJSON_GetObjectItemCaseSensitive(ad, "field_unit") : NULL;
    }
    if (unit != NULL) {
        double u = cJSON_IsString(unit) ? unit_per_nt_of(unit->valuestring) : NAN;
        if (!isfinite(u)) {
            (void)snprintf(err, err_len, "%s: prior \"field_unit\" must be \"uT\", \"nT\" or \"gauss\"", path);
            goto out;
        }
        scale = unit_per_nt / u; /* prior unit -> dump unit */
    }
    /* a 3d report's G outputs its own F (det G = 1): rescale to the reference magnitude */
    mode = cJSON_GetObjectItemCaseSensitive(root, "mode");
    field = cJSON_GetObjectItemCaseSensitive(root, "field");
    if (cJSON_IsString(mode) && strcmp(mode->valuestring, "3d") == 0 && isfinite(field_ref)) {
        if (!cJSON_IsNumber(field) || !(field->valuedouble > 0.0) || !isfinite(field->valuedouble)) {
            (void)snprintf(err, err_len, "%s: prior is a 3d report without a positive \"field\"", path);
            goto out;
        }
        gs = field_ref / (field->valuedouble * scale); /* its F in the dump unit */
        for (i = 0; i < 3; ++i) {
            for (j = 0; j < 3; ++j) {
                g[i][j] *= gs;
            }
        }
    }
    det = g[0][0] * (g[1][1] * g[2][2] - g[1][2] * g[2][1]) - g[0][1] * (g[1][0] * g[2][2] - g[1][2] * g[2][0]) +
          g[0][2] * (g[1][0] * g[2][1] - g[1][1] * g[2][0]);
    for (i = 0; i < 3; ++i) {
        for (j = 0; j < 3; ++j) {
            gnorm += g[i][j] * g[i][j];
        }
    }
    gnorm = sqrt(gnorm / 3.0); /* 1 for a rotation */
    if (!(fabs(det) > 1e-6 * gnorm * gnorm * gnorm)) {
        (void)snprintf(err, err_len, "%s: prior \"matrix\" is singular (det %g)", path, det);
        goto out;
    }
    for (i = 0; i < 3; ++i) {
        for (j = 0; j < 3; ++j) {
            prior->g[i][j] = (float)g[i][j];
        }
    }
    prior->v.x = (float)(v[0] * scale);
    prior->v.y = (float)(v[1] * scale);
    prior->v.z = (float)(v[2] * scale);
    prior->field = 0.0f;
    *g_scale = gs;
    rc = REPLAY_EXIT_OK;
out:
    cJSON_Delete(root);
    free(text);
    fclose(f);
    return rc;
}

static magcal_aided_t g_aided;

int replay_aided_run(const magcal_replay_csv_t *d, const magcal_vec3_t *m, const double *b_ned3,
                     size_t first, size_t end, const magcal_ellipsoid_cal_t *prior, replay_report_t *r,
                     magcal_ellipsoid_cal_t *cal, unsigned char *gate_row)
{
    magcal_aided_cfg_t cfg = MAGCAL_AIDED_CFG_DEFAULT;
    const double *roll = d->col[MAGCAL_REPLAY_COL_ROLL], *pitch = d->col[MAGCAL_REPLAY_COL_PITCH];
    const double *yaw = d->col[MAGCAL_REPLAY_COL_YAW], *dop = d->col[MAGCAL_REPLAY_COL_DOP];
    const double d2r = k_pi / 180.0;
    magcal_aided_result_t res;
    magcal_status_t st;
    size_t i, k;
    int first_fed = 1;

    if (prior != NULL) {
        cfg.prior = *prior;
    }
    if (r->aided_objective != NULL && strcmp(r->aided_objective, "vector") == 0) {
        cfg.objective = MAGCAL_AIDED_OBJ_VECTOR;
    }
    for (i = 0u; i < d->n_rows; ++i) {
        gate_row[i] = (i >= first && i < end) ? REPLAY_GATE_SKIPPED : REPLAY_GATE_NOT_CAL;
    }
    st = magcal_aided_init(&g_aided, &cfg);
    if (st != MAGCAL_OK && prior != NULL) {
        (void)snprintf(r->reason, sizeof r->reason, "%s", magcal_status_str(st));
        return REPLAY_EXIT_INPUT;
    }
    if (st != MAGCAL_OK) {
        fprintf(stderr, "magcal-replay: magcal_aided_init: %s\n", magcal_status_str(st));
        return REPLAY_EXIT_INTERNAL;
    }
    r->converged_at = -1;
    r->converged_row = -1;
    r->aided_skipped = 0u;
    for (i = first; i < end; ++i) {
        magcal_aided_epoch_t ep;
        magcal_aided_gate_t why = MAGCAL_AIDED_GATE_NONE;
        double dp = (dop != NULL) ? dop[i] : 0.0;
        if (!isfinite(b_ned3[3u * i]) || !isfinite(roll[i]) || !isfinite(pitch[i]) || !isfinite(yaw[i]) ||
            !isfinite(dp)) {
            r->aided_skipped++;
            continue;
        }
        ep.m = m[i];
        ep.roll_rad = (float)(roll[i] * d2r);
        ep.pitch_rad = (float)(pitch[i] * d2r);
        ep.yaw_rad = (float)(yaw[i] * d2r);
        ep.b_ref_ned.x = (float)b_ned3[3u * i];
        ep.b_ref_ned.y = (float)b_ned3[3u * i + 1u];
        ep.b_ref_ned.z = (float)b_ned3[3u * i + 2u];
        ep.dop = (float)dp;
        if (first_fed) {
            first_fed = 0;
            for (k = 0u; k < 3u; ++k) {
                r->b_ref_first[k] = b_ned3[3u * i + k];
            }
        }
        st = magcal_aided_update(&g_aided, &ep, &why);
        if (st != MAGCAL_OK && st != MAGCAL_ERR_GATED) {
            /* bad epoch content (|pitch| >= 90, dop < 0, ...): counted as skipped, reported */
            r->aided_skipped++;
            continue;
        }
        gate_row[i] = (st == MAGCAL_OK) ? (unsigned char)MAGCAL_AIDED_GATE_NONE : (unsigned char)why;
        if (st == MAGCAL_OK && r->converged_row < 0 &&
            magcal_aided_get(&g_aided, &res) != MAGCAL_ERR_TOO_FEW_POINTS &&
            (res.flags & MAGCAL_AIDED_FLAG_CONVERGED) != 0u) {
            r->converged_row = (long)i;
        }
    }
    memset(&res, 0, sizeof res);
    st = magcal_aided_get(&g_aided, &res);
    r->aided_status = replay_status_id(st);
    r->aided_status_code = (int)st;
    r->status = r->aided_status;
    r->status_code = (int)st;
    r->aided_seen = res.n_seen;
    r->aided_accepted = res.n_accepted;
    for (k = 0u; k < 5u; ++k) {
        r->aided_gated[k] = res.gated[k];
    }
    if (st != MAGCAL_OK && st != MAGCAL_ERR_UNOBSERVABLE && st != MAGCAL_ERR_NOT_CONVERGED) {
        r->aided_seen = 0u;
        (void)snprintf(r->reason, sizeof r->reason, "%s: no estimate (fewer than %u accepted epochs)",
                       magcal_status_str(st), (unsigned)cfg.min_epochs);
        r->have_aided = 0;
        return REPLAY_EXIT_CAL_FAILED;
    }
    if (st != MAGCAL_OK) {
        (void)snprintf(r->reason, sizeof r->reason, "%s", magcal_status_str(st));
    }
    r->have_aided = 1;
    *cal = res.cal;
    r->converged_at = res.converged_at > 0u ? (long)res.converged_at : -1;
    r->aided_flags = res.flags;
    r->n_prior_dirs = res.n_prior_dirs;
    r->min_eig = res.min_eig;
    r->weak_std = res.weak_std;
    r->resid_rms_aided = res.resid_rms;
    r->resid_f_rms_aided = res.resid_f_rms;
    r->n_total_field = res.n_total_field;
    r->have_3d = 1;
    r->model3 = "aided";
    r->off3[0] = res.cal.v.x;
    r->off3[1] = res.cal.v.y;
    r->off3[2] = res.cal.v.z;
    for (i = 0u; i < 3u; ++i) {
        for (k = 0u; k < 3u; ++k) {
            r->mat3[i][k] = res.cal.g[i][k];
        }
    }
    r->field3 = res.cal.field;
    r->n_used = res.n_accepted;
    r->n_outliers = res.gated[1] + res.gated[2] + res.gated[3] + res.gated[4];
    return REPLAY_EXIT_OK;
}
