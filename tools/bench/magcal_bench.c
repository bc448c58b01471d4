/*
 * magcal_bench: deterministic driver of the performance bench (tools/bench/run_bench.py).
 *
 * One generated data set per n: a distorted compass-swing ring (hard iron (300, -200), semi-axes
 * 520 x 410 turned 30 deg, Gaussian noise sigma 3, one full turn with jitter) with 12 % singular
 * points interleaved in the sample sequence: 6 % scattered over a box 3 R around the ring, 3 % a
 * dense driver-glitch cluster 6 R away, 3 % one burst of consecutive samples displaced 0.35 R
 * outwards. The generator is an xorshift32 PRNG with a fixed seed, so every n gives the same
 * points on every machine (the libm of the host may change the last bit of a sample).
 *
 * Modes (n <= MAGCAL_MAX_SAMPLES of this build, 4096 in tools/bench/CMakeLists.txt):
 *   magcal_bench info N             key=value lines: automatic eps / eps' / MinPts, the result of
 *                                   the default calibration, a check that the three OPTICS
 *                                   variants agree bit for bit, workspace sizes
 *   magcal_bench dump N FILE        the N points as CSV "x,y,outlier,magcal_filter_inlier" (%.9g:
 *                                   float32 exact; last column: the default OPTICS filter mask)
 *   magcal_bench run KERNEL N       run KERNEL once (under callgrind --toggle-collect=<its
 *                                   library function>); the setup outside the kernel is not
 *                                   collected
 *   magcal_bench time KERNEL N REPS wall clock (CLOCK_MONOTONIC) of REPS runs; prints
 *                                   "median_s=... min_s=..."
 * Kernels (library function the runner toggles on):
 *   optics_classic   magcal_optics_run  CLASSIC heap + BRUTE search, eps = automatic eps
 *   optics_improved  magcal_optics_run  IMPROVED unordered seeds + BRUTE
 *   optics_indexed   magcal_optics_run  IMPROVED + GRID (the calibrator's default)
 *   optics_classic_grid magcal_optics_run CLASSIC + GRID (context: what the index alone buys)
 *   optics_classic_inf, optics_improved_inf  magcal_optics_run with eps = +INF (sklearn's default
 *                    max_eps; the seed list then holds every unprocessed point), BRUTE
 *   optics_filter    magcal_optics_filter  auto params + ordering + extraction + largest cluster
 *                    (the calibrator's path: its grid covers only a window around the ring)
 *   auto_params      magcal_optics_auto_params (subtract from optics_filter for its ordering)
 *   dbscan           magcal_dbscan_run  eps = automatic eps', MinPts = automatic, GRID
 *   dbscan_brute     magcal_dbscan_run  same with BRUTE
 *   ellipse          magcal_ellipse_fit on the true inliers
 *   consensus        magcal_consensus_run (default cfg) with the OPTICS filter mask as candidates
 *   calibration      magcal_calibrator_run, default cfg (samples pushed before, not counted)
 *   calibration_push magcal_calibrator_push x N + magcal_calibrator_run (timing: init, push, run)
 *   heading          magcal_heading_compute, one sample, with the calibration of the data set
 *   optics3_filter   magcal_optics_filter3 (automatic parameters) on a 3-D set: a noisy ellipsoid
 *                    shell (uniform directions, F = 500, offset (300, -200, 150), axes 1.1/0.93/1.04
 *                    x F, sigma 3) with 5 % scattered points (radius x 1.7..2.5) and 3 % one stuck
 *                    burst 0.8 R outside (bench_generate3())
 *   optics3_classic, optics3_improved  magcal_optics_run3 CLASSIC / IMPROVED + GRID at
 *                    eps = the automatic eps' of that set, MinPts 4
 *   optics3_classic_brute, optics3_improved_brute  the same with BRUTE
 *   auto_params3     magcal_optics_auto_params3 on that set
 *   ellipsoid3       magcal_ellipsoid_fit (default cfg) on the inliers of magcal_optics_filter3
 *                    of that set (the harness's 3d pipeline; the filter is not counted)
 *   aided            magcal_aided_update x N epochs of a synthetic road drive (bench_generate_drive:
 *                    1 deg RMS tilt, 90-degree turns; default cfg, combined objective); callgrind
 *                    counts all N calls, the runner divides by N
 *   aided_vector     the same with the vector objective
 * Only in magcal_bench_sorted (built against a library copy with MAGCAL_OPTICS_BENCH_SORTED_LIST,
 * tools/bench/CMakeLists.txt; never in a shipped build):
 *   optics_sorted_list      magcal_optics_run with the source paper's classic seed list (re-sorted
 *                           by reachability whenever it changed), BRUTE, eps = automatic eps
 *   optics_sorted_list_inf  the same with eps = +INF
 *   ("info" then also checks that the sorted list gives the improved mode's outputs bit for bit)
 */
#define _POSIX_C_SOURCE 199309L

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "magcal/calibrator.h"
#include "magcal/consensus.h"
#include "magcal/dbscan.h"
#include "magcal/ellipse.h"
#include "magcal/ellipsoid.h"
#include "magcal/heading.h"
#include "magcal/optics.h"

#ifdef MAGCAL_OPTICS_BENCH_SORTED_LIST
/* the bench-only seed-list mode of src/optics_core.h (MAGCAL_OPTICS_SORTED_LIST_) */
#define BENCH_SORTED_LIST ((magcal_optics_order_t)2)
#endif

#include "bench_data.h"

/* magcal_ellipsoid_fit's fixed scratch (the workspace-free fit: no per-sample storage) */
static magcal_ellipsoid_fit_scratch_t g_fit_scratch;

#define NMAX ((size_t)MAGCAL_MAX_SAMPLES)

static magcal_vec2_t g_pts[NMAX];
static uint8_t g_outlier[NMAX];
static uint8_t g_truth_inlier[NMAX];
static uint32_t g_work[(MAGCAL_CALIBRATOR_WORKSPACE_LEN(NMAX) + 3u) / 4u];
static uint16_t g_order[NMAX];
static float g_reach[NMAX];
static float g_core[NMAX];
static uint16_t g_order2[NMAX];
static float g_reach2[NMAX];
static float g_core2[NMAX];
static int16_t g_labels[NMAX];
static uint8_t g_mask[NMAX];
static uint8_t g_mask2[NMAX];
static magcal_vec2_t g_buf[NMAX];
static magcal_calibrator_t g_cal;

/* Auto parameters of the current data set. */
static float g_eps;
static float g_eps_prime;
static uint16_t g_min_pts;

static uint8_t g_kind[NMAX];

static void generate(size_t n)
{
    size_t i;
    bench_generate(g_pts, g_kind, n);
    for (i = 0u; i < n; ++i) {
        g_outlier[i] = (uint8_t)(g_kind[i] != 0u);
        g_truth_inlier[i] = (uint8_t)(g_kind[i] == 0u);
    }
}

/* ------------------------------------------------------------------ 3-D set */

static magcal_vec3_t g_pts3[NMAX];
static magcal_vec3_t g_kept3[NMAX];
static uint32_t g_work3[(MAGCAL_OPTICS3_FILTER_WORKSPACE_LEN(NMAX) + 3u) / 4u];
static magcal_aided_epoch_t g_ep[NMAX];
static magcal_aided_t g_aided;

/* ------------------------------------------------------------------ kernels */

static int fail(const char *what, magcal_status_t st)
{
    fprintf(stderr, "magcal_bench: %s failed with status %d\n", what, (int)st);
    return 2;
}

static magcal_status_t auto_params(size_t n)
{
    return magcal_optics_auto_params(g_pts, n, g_work, sizeof g_work, &g_eps, &g_min_pts,
                                     &g_eps_prime);
}

static magcal_status_t optics_variant(size_t n, magcal_optics_order_t order, magcal_neighbors_t nbr,
                                      uint16_t *o, float *re, float *co)
{
    magcal_optics_cfg_t cfg = MAGCAL_OPTICS_CFG_DEFAULT;
    cfg.eps = g_eps;
    cfg.eps_prime = g_eps_prime;
    cfg.min_pts = g_min_pts;
    cfg.order = order;
    cfg.neighbors = nbr;
    return magcal_optics_run(&cfg, g_pts, n, g_work, sizeof g_work, o, re, co, NULL, NULL);
}

static magcal_status_t calib_init(void)
{
    magcal_calibrator_cfg_t cfg = MAGCAL_CALIBRATOR_CFG_DEFAULT;
    return magcal_calibrator_init(&g_cal, &cfg, g_buf, NMAX, g_work, sizeof g_work);
}

static magcal_status_t calib_push(size_t n)
{
    size_t i;
    for (i = 0u; i < n; ++i) {
        magcal_status_t st = magcal_calibrator_push(&g_cal, g_pts[i]);
        if (st != MAGCAL_OK) {
            return st;
        }
    }
    return MAGCAL_OK;
}

static magcal_status_t calib_full(size_t n, magcal_cal2d_t *cal, magcal_cal_report_t *rep)
{
    magcal_status_t st = calib_init();
    if (st == MAGCAL_OK) {
        st = calib_push(n);
    }
    if (st == MAGCAL_OK) {
        st = magcal_calibrator_run(&g_cal, cal, rep);
    }
    return st;
}

static magcal_status_t dbscan(size_t n, magcal_neighbors_t nbr)
{
    magcal_dbscan_cfg_t cfg = MAGCAL_DBSCAN_CFG_DEFAULT;
    cfg.eps = g_eps_prime;
    cfg.min_pts = g_min_pts;
    cfg.neighbors = nbr;
    return magcal_dbscan_run(&cfg, g_pts, n, g_work, sizeof g_work, g_labels, NULL, NULL);
}

static magcal_status_t optics_filter(size_t n, magcal_optics_result_t *info)
{
    magcal_optics_cfg_t cfg = MAGCAL_OPTICS_CFG_DEFAULT;
    return magcal_optics_filter(&cfg, g_pts, n, g_work, sizeof g_work, g_mask, info);
}

/* Run one kernel once. Setup the kernel depends on (auto parameters, a calibration, a filter
 * mask) is done here too but outside the toggled library function. */
static int run_kernel(const char *k, size_t n, int quiet)
{
    magcal_status_t st = MAGCAL_OK;
    magcal_cal2d_t cal = MAGCAL_CAL2D_IDENTITY;
    magcal_cal_report_t rep;

    if (strncmp(k, "optics_", 7) == 0 && strcmp(k, "optics_filter") != 0) {
        st = auto_params(n);
        if (st != MAGCAL_OK) {
            return fail("auto params", st);
        }
        if (strcmp(k, "optics_classic") == 0) {
            st = optics_variant(n, MAGCAL_OPTICS_CLASSIC, MAGCAL_NEIGHBORS_BRUTE, g_order, g_reach,
                                g_core);
        } else if (strcmp(k, "optics_improved") == 0) {
            st = optics_variant(n, MAGCAL_OPTICS_IMPROVED, MAGCAL_NEIGHBORS_BRUTE, g_order, g_reach,
                                g_core);
        } else if (strcmp(k, "optics_indexed") == 0) {
            st = optics_variant(n, MAGCAL_OPTICS_IMPROVED, MAGCAL_NEIGHBORS_GRID, g_order, g_reach,
                                g_core);
        } else if (strcmp(k, "optics_classic_inf") == 0 || strcmp(k, "optics_improved_inf") == 0) {
            g_eps = INFINITY; /* scikit-learn's default max_eps: every point is a neighbour */
            st = optics_variant(n, k[7] == 'c' ? MAGCAL_OPTICS_CLASSIC : MAGCAL_OPTICS_IMPROVED,
                                MAGCAL_NEIGHBORS_BRUTE, g_order, g_reach, g_core);
        } else if (strcmp(k, "optics_classic_grid") == 0) {
            st = optics_variant(n, MAGCAL_OPTICS_CLASSIC, MAGCAL_NEIGHBORS_GRID, g_order, g_reach,
                                g_core);
#ifdef MAGCAL_OPTICS_BENCH_SORTED_LIST
        } else if (strcmp(k, "optics_sorted_list") == 0 ||
                   strcmp(k, "optics_sorted_list_inf") == 0) {
            if (strcmp(k, "optics_sorted_list_inf") == 0) {
                g_eps = INFINITY;
            }
            st = optics_variant(n, BENCH_SORTED_LIST, MAGCAL_NEIGHBORS_BRUTE, g_order, g_reach,
                                g_core);
#endif
        } else {
            fprintf(stderr, "magcal_bench: unknown kernel %s\n", k);
            return 1;
        }
        if (st != MAGCAL_OK) {
            return fail(k, st);
        }
        if (!quiet) {
            printf("first=%u last=%u\n", (unsigned)g_order[0], (unsigned)g_order[n - 1u]);
        }
    } else if (strcmp(k, "optics_filter") == 0) {
        magcal_optics_result_t info;
        st = optics_filter(n, &info);
        if (st != MAGCAL_OK) {
            return fail(k, st);
        }
        if (!quiet) {
            printf("inliers=%u\n", (unsigned)info.n_inliers);
        }
    } else if (strcmp(k, "auto_params") == 0) {
        st = auto_params(n);
        if (st != MAGCAL_OK) {
            return fail(k, st);
        }
    } else if (strcmp(k, "dbscan") == 0 || strcmp(k, "dbscan_brute") == 0) {
        st = auto_params(n);
        if (st == MAGCAL_OK) {
            st = dbscan(n, k[6] == '\0' ? MAGCAL_NEIGHBORS_GRID : MAGCAL_NEIGHBORS_BRUTE);
        }
        if (st != MAGCAL_OK) {
            return fail(k, st);
        }
    } else if (strcmp(k, "ellipse") == 0) {
        magcal_ellipse_t e;
        st = magcal_ellipse_fit(g_pts, n, g_truth_inlier, &e);
        if (st != MAGCAL_OK) {
            return fail(k, st);
        }
        if (!quiet) {
            printf("centre=%.3f,%.3f\n", (double)e.center.x, (double)e.center.y);
        }
    } else if (strcmp(k, "consensus") == 0) {
        magcal_consensus_cfg_t cc = MAGCAL_CONSENSUS_CFG_DEFAULT;
        magcal_consensus_result_t res;
        st = optics_filter(n, NULL);
        if (st == MAGCAL_OK) {
            st = magcal_consensus_run(&cc, g_pts, n, g_mask, g_work, sizeof g_work, g_mask2, &res);
        }
        if (st != MAGCAL_OK) {
            return fail(k, st);
        }
    } else if (strcmp(k, "calibration") == 0 || strcmp(k, "calibration_push") == 0) {
        st = calib_full(n, &cal, &rep);
        if (st != MAGCAL_OK) {
            return fail(k, st);
        }
    } else if (strcmp(k, "ellipsoid3") == 0) {
        magcal_optics_cfg_t c3 = MAGCAL_OPTICS_CFG_DEFAULT;
        magcal_ellipsoid_cfg_t ec = MAGCAL_ELLIPSOID_CFG_DEFAULT;
        magcal_ellipsoid_result_t er;
        size_t i, nk = 0u;
        bench_generate3(g_pts3, n);
        st = magcal_optics_filter3(&c3, g_pts3, n, g_work3, sizeof g_work3, g_mask, NULL);
        for (i = 0u; st == MAGCAL_OK && i < n; ++i) {
            if (g_mask[i] != 0u) {
                g_kept3[nk++] = g_pts3[i];
            }
        }
        if (st == MAGCAL_OK) {
            st = magcal_ellipsoid_fit(g_kept3, nk, &ec, &g_fit_scratch, &er);
        }
        if (st != MAGCAL_OK) {
            return fail(k, st);
        }
        if (!quiet) {
            printf("kept=%u used=%u V=%.3f,%.3f,%.3f\n", (unsigned)nk, (unsigned)er.n_used, (double)er.cal.v.x,
                   (double)er.cal.v.y, (double)er.cal.v.z);
        }
    } else if (strcmp(k, "aided") == 0 || strcmp(k, "aided_vector") == 0) {
        magcal_aided_cfg_t ac = MAGCAL_AIDED_CFG_DEFAULT;
        magcal_aided_result_t ar;
        size_t i;
        if (strcmp(k, "aided_vector") == 0) {
            ac.objective = MAGCAL_AIDED_OBJ_VECTOR;
        }
        bench_generate_drive(g_ep, n);
        st = magcal_aided_init(&g_aided, &ac);
        for (i = 0u; st == MAGCAL_OK && i < n; ++i) {
            st = magcal_aided_update(&g_aided, &g_ep[i], NULL);
            if (st == MAGCAL_ERR_GATED) {
                st = MAGCAL_OK;
            }
        }
        if (st != MAGCAL_OK) {
            return fail(k, st);
        }
        st = magcal_aided_get(&g_aided, &ar);
        if (!quiet) {
            printf("status=%d accepted=%u V=%.3f,%.3f,%.3f\n", (int)st, (unsigned)ar.n_accepted, (double)ar.cal.v.x,
                   (double)ar.cal.v.y, (double)ar.cal.v.z);
        }
    } else if (strncmp(k, "optics3_", 8) == 0 || strcmp(k, "auto_params3") == 0) {
        magcal_optics_cfg_t c3 = MAGCAL_OPTICS_CFG_DEFAULT;
        magcal_optics_result_t info;
        bench_generate3(g_pts3, n);
        if (strcmp(k, "optics3_filter") == 0) {
            st = magcal_optics_filter3(&c3, g_pts3, n, g_work3, sizeof g_work3, g_mask, &info);
            if (st == MAGCAL_OK && !quiet) {
                printf("eps=%.3f inliers=%u clusters=%u\n", (double)info.eps_prime,
                       (unsigned)info.n_inliers, (unsigned)info.n_clusters);
            }
        } else {
            st = magcal_optics_auto_params3(g_pts3, n, g_work3, sizeof g_work3, &c3.eps,
                                            &c3.min_pts, &c3.eps_prime);
            if (st == MAGCAL_OK && strcmp(k, "auto_params3") != 0) {
                c3.eps = c3.eps_prime; /* the run at eps = eps' (the automatic eps is R) */
                c3.order = strncmp(k, "optics3_classic", 15) == 0 ? MAGCAL_OPTICS_CLASSIC
                                                                  : MAGCAL_OPTICS_IMPROVED;
                c3.neighbors = strstr(k, "_brute") != NULL ? MAGCAL_NEIGHBORS_BRUTE
                                                           : MAGCAL_NEIGHBORS_GRID;
                st = magcal_optics_run3(&c3, g_pts3, n, g_work3, sizeof g_work3, g_order, g_reach,
                                        g_core, NULL, NULL);
            }
        }
        if (st != MAGCAL_OK) {
            return fail(k, st);
        }
    } else if (strcmp(k, "heading") == 0) {
        float mag = 0.0f, tru = 0.0f;
        st = calib_full(n, &cal, &rep);
        if (st != MAGCAL_OK) {
            return fail("calibration", st);
        }
        st = magcal_heading_compute(&cal, g_pts[1], 2.5f, &mag, &tru);
        if (st != MAGCAL_OK) {
            return fail(k, st);
        }
        if (!quiet) {
            printf("heading=%.3f\n", (double)mag);
        }
    } else {
        fprintf(stderr, "magcal_bench: unknown kernel %s\n", k);
        return 1;
    }
    return 0;
}

/* ------------------------------------------------------------------ modes */

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static int mode_time(const char *k, size_t n, size_t reps)
{
    static double t[1001];
    size_t i;
    if (reps < 1u || reps > 1000u) {
        fprintf(stderr, "magcal_bench: REPS must be 1..1000\n");
        return 1;
    }
    if (strcmp(k, "calibration_push") != 0 && strcmp(k, "optics_indexed") != 0 &&
        strcmp(k, "optics_classic") != 0 && strcmp(k, "optics_filter") != 0) {
        fprintf(stderr, "magcal_bench: time supports calibration_push, optics_filter, "
                        "optics_indexed, optics_classic\n");
        return 1;
    }
    if (run_kernel(k, n, 1) != 0) { /* warm-up: page in code and data, check it works */
        return 2;
    }
    for (i = 0u; i < reps; ++i) {
        double t0 = now_s();
        magcal_status_t st = MAGCAL_OK;
        if (strcmp(k, "calibration_push") == 0) {
            magcal_cal2d_t cal = MAGCAL_CAL2D_IDENTITY;
            magcal_cal_report_t rep;
            st = calib_full(n, &cal, &rep);
        } else if (strcmp(k, "optics_filter") == 0) {
            st = optics_filter(n, NULL);
        } else if (strcmp(k, "optics_indexed") == 0) {
            st = optics_variant(n, MAGCAL_OPTICS_IMPROVED, MAGCAL_NEIGHBORS_GRID, g_order, g_reach,
                                g_core);
        } else {
            st = optics_variant(n, MAGCAL_OPTICS_CLASSIC, MAGCAL_NEIGHBORS_BRUTE, g_order, g_reach,
                                g_core);
        }
        t[i] = now_s() - t0;
        if (st != MAGCAL_OK) {
            return fail(k, st);
        }
    }
    qsort(t, reps, sizeof t[0], cmp_double);
    printf("median_s=%.9f min_s=%.9f reps=%u\n",
           reps % 2u ? t[reps / 2u] : 0.5 * (t[reps / 2u - 1u] + t[reps / 2u]), t[0],
           (unsigned)reps);
    return 0;
}

static int same_arrays(size_t n)
{
    return memcmp(g_order, g_order2, n * sizeof g_order[0]) == 0 &&
           memcmp(g_reach, g_reach2, n * sizeof(float)) == 0 &&
           memcmp(g_core, g_core2, n * sizeof(float)) == 0;
}

static int mode_info(size_t n)
{
    magcal_status_t st;
    magcal_cal2d_t cal = MAGCAL_CAL2D_IDENTITY;
    magcal_cal_report_t rep;
    magcal_optics_result_t info;
    size_t i, n_out = 0u, rej_true = 0u, kept_false = 0u;
    int same = 1;

    st = auto_params(n);
    if (st != MAGCAL_OK) {
        return fail("auto params", st);
    }
    printf("n=%u\nmax_samples=%u\neps=%.9g\neps_prime=%.9g\nmin_pts=%u\n", (unsigned)n,
           (unsigned)NMAX, (double)g_eps, (double)g_eps_prime, (unsigned)g_min_pts);
    for (i = 0u; i < n; ++i) {
        n_out += g_outlier[i];
    }
    printf("true_outliers=%u\n", (unsigned)n_out);

    /* the three measured variants must give bit-identical outputs (else the comparison is moot) */
    st = optics_variant(n, MAGCAL_OPTICS_CLASSIC, MAGCAL_NEIGHBORS_BRUTE, g_order, g_reach, g_core);
    if (st != MAGCAL_OK) {
        return fail("optics classic", st);
    }
    st = optics_variant(n, MAGCAL_OPTICS_IMPROVED, MAGCAL_NEIGHBORS_BRUTE, g_order2, g_reach2,
                        g_core2);
    same = same && st == MAGCAL_OK && same_arrays(n);
    st = optics_variant(n, MAGCAL_OPTICS_IMPROVED, MAGCAL_NEIGHBORS_GRID, g_order2, g_reach2,
                        g_core2);
    same = same && st == MAGCAL_OK && same_arrays(n);
    printf("optics_variants_identical=%d\n", same);
#ifdef MAGCAL_OPTICS_BENCH_SORTED_LIST
    st = optics_variant(n, BENCH_SORTED_LIST, MAGCAL_NEIGHBORS_BRUTE, g_order2, g_reach2, g_core2);
    printf("optics_sorted_list_identical=%d\n", st == MAGCAL_OK && same_arrays(n));
#endif

    st = optics_filter(n, &info);
    if (st != MAGCAL_OK) {
        return fail("optics filter", st);
    }
    printf("filter_inliers=%u\nfilter_clusters=%u\n", (unsigned)info.n_inliers,
           (unsigned)info.n_clusters);

    st = calib_full(n, &cal, &rep);
    printf("calibration_status=%d\n", (int)st);
    if (st != MAGCAL_OK) {
        return fail("calibration", st);
    }
    for (i = 0u; i < n; ++i) {
        int inl = 0;
        (void)magcal_calibrator_inlier(&g_cal, i, &inl);
        rej_true += (size_t)(inl == 0 && g_outlier[i] == 0u);
        kept_false += (size_t)(inl != 0 && g_outlier[i] != 0u);
    }
    printf("calibration_used=%u\ncalibration_rejected_inliers=%u\ncalibration_kept_outliers=%u\n",
           (unsigned)rep.used, (unsigned)rej_true, (unsigned)kept_false);
    printf("calibration_centre=%.4f,%.4f\ncalibration_axes=%.4f,%.4f\n",
           (double)rep.ellipse.center.x, (double)rep.ellipse.center.y,
           (double)rep.ellipse.semi_minor, (double)rep.ellipse.semi_major);
    printf("calibration_est_heading_err_deg=%.4f\n", (double)rep.est_heading_err_deg);
    /* size macros at this build's capacity and at the shipped default 1024 */
    printf("calibrator_workspace_bytes_%u=%u\n", (unsigned)NMAX,
           (unsigned)MAGCAL_CALIBRATOR_WORKSPACE_LEN(NMAX));
    printf("calibrator_workspace_bytes_1024=%u\n",
           (unsigned)MAGCAL_CALIBRATOR_WORKSPACE_LEN(1024u));
    printf("optics_filter_workspace_bytes_1024=%u\n",
           (unsigned)MAGCAL_OPTICS_FILTER_WORKSPACE_LEN(1024u));
    printf("consensus_workspace_bytes_1024=%u\n", (unsigned)MAGCAL_CONSENSUS_WORKSPACE_LEN(1024u));
    printf("dbscan_workspace_bytes_1024=%u\n", (unsigned)MAGCAL_DBSCAN_WORKSPACE_LEN(1024u));
    printf("masks_bytes_1024=%u\n", (unsigned)MAGCAL_CALIBRATOR_MASKS_LEN(1024u));
    printf("sample_bytes=%u\ncalibrator_instance_bytes=%u\n", (unsigned)sizeof(magcal_vec2_t),
           (unsigned)sizeof(magcal_calibrator_t));
    return 0;
}

static int mode_dump(size_t n, const char *path)
{
    FILE *f;
    size_t i;
    magcal_status_t st = optics_filter(n, NULL); /* the calibrator's filter, for comparison */
    if (st != MAGCAL_OK) {
        return fail("optics filter", st);
    }
    f = fopen(path, "w");
    if (f == NULL) {
        fprintf(stderr, "magcal_bench: cannot write %s\n", path);
        return 1;
    }
    fprintf(f, "x,y,outlier,magcal_filter_inlier\n");
    for (i = 0u; i < n; ++i) {
        fprintf(f, "%.9g,%.9g,%u,%u\n", (double)g_pts[i].x, (double)g_pts[i].y,
                (unsigned)g_outlier[i], (unsigned)g_mask[i]);
    }
    return fclose(f) == 0 ? 0 : 1;
}

static int usage(void)
{
    fprintf(stderr,
            "usage: magcal_bench info N | dump N FILE | run KERNEL N | time KERNEL N REPS\n"
            "       (N = 16..%u; see the comment at the top of magcal_bench.c)\n",
            (unsigned)NMAX);
    return 1;
}

static int parse_n(const char *s, size_t *n)
{
    char *end = NULL;
    unsigned long v = strtoul(s, &end, 10);
    if (end == s || *end != '\0' || v < 16ul || v > (unsigned long)NMAX) {
        return 0;
    }
    *n = (size_t)v;
    return 1;
}

int main(int argc, char **argv)
{
    size_t n = 0u;
    if (argc >= 3 && strcmp(argv[1], "info") == 0 && parse_n(argv[2], &n)) {
        generate(n);
        return mode_info(n);
    }
    if (argc == 4 && strcmp(argv[1], "dump") == 0 && parse_n(argv[2], &n)) {
        generate(n);
        return mode_dump(n, argv[3]);
    }
    if (argc == 4 && strcmp(argv[1], "run") == 0 && parse_n(argv[3], &n)) {
        generate(n);
        return run_kernel(argv[2], n, 0);
    }
    if (argc == 5 && strcmp(argv[1], "time") == 0 && parse_n(argv[3], &n)) {
        generate(n);
        return mode_time(argv[2], n, (size_t)strtoul(argv[4], NULL, 10));
    }
    return usage();
}
