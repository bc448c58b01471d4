/*
 * libFuzzer harness for the geometry stages on their own: OPTICS (both orderings, both
 * neighbour searches), ExtractDBSCAN, largest cluster, the one-call filter, the automatic
 * parameters, DBSCAN, and the ellipse fit, with fuzzed eps, eps', MinPts and enums.
 *
 * Input layout (little endian; missing bytes read as 0):
 *   f32 eps, f32 eps_prime (raw bits: NaN, Inf, negative, subnormal are legal fuzz values)
 *   u8  min_pts (raw), u8 flags (bit 0-1 order enum raw, bit 2-3 neighbours enum raw,
 *       bit 4 sample format as fuzz_calibrator.c), f32 scale (format 1)
 *   then samples (8 bytes f32 x,y or 4 bytes i16 x,y times scale), at most MAGCAL_MAX_SAMPLES.
 *
 * Invariants: documented statuses only; outputs untouched on failure (sentinels); on success
 * the ordering is a permutation, reach/core are >= 0 or +Inf, labels are -1 or < n_clusters,
 * the inlier mask is 0/1 and counts agree; CLASSIC/IMPROVED and BRUTE/GRID give bit-identical
 * results (optics.h "Determinism"); an OK ellipse fit has finite 0 < r1 <= r2 and residual.
 */
#include <math.h>

#include "fuzz_common.h"
#include "magcal/dbscan.h"
#include "magcal/ellipse.h"
#include "magcal/optics.h"

#define FZ_N MAGCAL_MAX_SAMPLES
#define FZ_WORK_LEN                                                                                \
    (MAGCAL_OPTICS_FILTER_WORKSPACE_LEN(FZ_N) > MAGCAL_DBSCAN_WORKSPACE_LEN(FZ_N)                  \
         ? MAGCAL_OPTICS_FILTER_WORKSPACE_LEN(FZ_N)                                                \
         : MAGCAL_DBSCAN_WORKSPACE_LEN(FZ_N))

static magcal_vec2_t fz_pts[FZ_N];
static uint32_t fz_work[(FZ_WORK_LEN + 3u) / 4u];
static uint16_t fz_order[2][FZ_N];
static float fz_reach[2][FZ_N];
static float fz_core[2][FZ_N];
static uint16_t fz_pred[2][FZ_N];
static int16_t fz_labels[FZ_N];
static int16_t fz_labels2[FZ_N];
static uint8_t fz_mask[FZ_N];
static uint8_t fz_seen[FZ_N];

static int fz_all_finite(size_t n)
{
    size_t i;
    for (i = 0u; i < n; ++i) {
        if (!isfinite(fz_pts[i].x) || !isfinite(fz_pts[i].y)) {
            return 0;
        }
    }
    return 1;
}

static magcal_status_t fz_optics(const magcal_optics_cfg_t *cfg, size_t n, int slot)
{
    magcal_optics_result_t info;
    magcal_status_t st;
    size_t i;
    (void)memset(fz_order[slot], 0xEE, sizeof fz_order[slot]);
    st = magcal_optics_run(cfg, fz_pts, n, fz_work, sizeof fz_work, fz_order[slot], fz_reach[slot],
                           fz_core[slot], fz_pred[slot], &info);
    FUZZ_CHECK(st == MAGCAL_OK || st == MAGCAL_ERR_ARG || st == MAGCAL_ERR_TOO_FEW_POINTS ||
                   st == MAGCAL_ERR_NONFINITE,
               "optics_run status");
    if (st != MAGCAL_OK) {
        for (i = 0u; i < n; ++i) {
            FUZZ_CHECK(fz_order[slot][i] == 0xEEEEu, "optics_run wrote order on failure");
        }
        return st;
    }
    (void)memset(fz_seen, 0, n);
    for (i = 0u; i < n; ++i) {
        uint16_t o = fz_order[slot][i];
        FUZZ_CHECK(o < n && fz_seen[o] == 0u, "ordering is not a permutation");
        fz_seen[o] = 1u;
        FUZZ_CHECK(fz_reach[slot][i] >= 0.0f, "reach negative or NaN");
        FUZZ_CHECK(fz_core[slot][i] >= 0.0f, "core negative or NaN");
        FUZZ_CHECK(fz_pred[slot][i] == MAGCAL_OPTICS_NO_PRED || fz_pred[slot][i] < n, "pred range");
    }
    return st;
}

static void fz_same(size_t n, const char *what)
{
    FUZZ_CHECK(memcmp(fz_order[0], fz_order[1], n * sizeof fz_order[0][0]) == 0, what);
    FUZZ_CHECK(memcmp(fz_reach[0], fz_reach[1], n * sizeof fz_reach[0][0]) == 0, what);
    FUZZ_CHECK(memcmp(fz_core[0], fz_core[1], n * sizeof fz_core[0][0]) == 0, what);
    FUZZ_CHECK(memcmp(fz_pred[0], fz_pred[1], n * sizeof fz_pred[0][0]) == 0, what);
}

static void fz_labels_ok(const int16_t *labels, size_t n, uint16_t n_clusters)
{
    size_t i;
    for (i = 0u; i < n; ++i) {
        FUZZ_CHECK(labels[i] == MAGCAL_OPTICS_NOISE || (labels[i] >= 0 && labels[i] < (int)n_clusters),
                   "label range");
    }
}

static void fz_largest(const int16_t *labels, size_t n)
{
    int16_t id = 99;
    uint16_t cnt = 0u;
    size_t i, k = 0u;
    magcal_status_t st;
    (void)memset(fz_mask, 7, n);
    st = magcal_optics_largest_cluster(labels, n, fz_work, sizeof fz_work, fz_mask, &id, &cnt);
    FUZZ_CHECK(st == MAGCAL_OK || st == MAGCAL_ERR_ALL_NOISE, "largest_cluster status");
    if (st != MAGCAL_OK) {
        for (i = 0u; i < n; ++i) {
            FUZZ_CHECK(fz_mask[i] == 7u && labels[i] == MAGCAL_OPTICS_NOISE, "largest_cluster failure");
        }
        return;
    }
    for (i = 0u; i < n; ++i) {
        FUZZ_CHECK(fz_mask[i] == (labels[i] == id ? 1u : 0u), "largest_cluster mask");
        k += fz_mask[i];
    }
    FUZZ_CHECK(k == cnt && cnt >= 1u, "largest_cluster count");
}

static void fz_ellipse(size_t n)
{
    magcal_ellipse_t e;
    magcal_ellipse_t sentinel;
    magcal_status_t st;
    (void)memset(&e, 0x5A, sizeof e);
    sentinel = e;
    st = magcal_ellipse_fit(fz_pts, n, NULL, &e);
    FUZZ_CHECK(st == MAGCAL_OK || st == MAGCAL_ERR_TOO_FEW_POINTS || st == MAGCAL_ERR_NONFINITE ||
                   st == MAGCAL_ERR_DEGENERATE || st == MAGCAL_ERR_ILL_CONDITIONED ||
                   st == MAGCAL_ERR_HYPERBOLA || st == MAGCAL_ERR_PARABOLA ||
                   st == MAGCAL_ERR_IMAGINARY,
               "ellipse_fit status");
    if (st != MAGCAL_OK) {
        FUZZ_CHECK(memcmp(&e, &sentinel, sizeof e) == 0, "ellipse_fit wrote output on failure");
        return;
    }
    FUZZ_CHECK(isfinite(e.semi_minor) && isfinite(e.semi_major) && e.semi_minor > 0.0f &&
                   e.semi_minor <= e.semi_major,
               "ellipse axes");
    FUZZ_CHECK(isfinite(e.center.x) && isfinite(e.center.y), "ellipse centre");
    FUZZ_CHECK(isfinite(e.residual_rms) && e.residual_rms >= 0.0f, "ellipse residual");
    FUZZ_CHECK(e.n_used == (uint16_t)n, "ellipse n_used");
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    fuzz_in_t in = {data, size, 0u};
    float eps = fuzz_f32(&in);
    float eps_prime = fuzz_f32(&in);
    uint8_t min_pts = fuzz_u8(&in);
    uint8_t flags = fuzz_u8(&in);
    float scale = fuzz_f32(&in);
    int as_int16 = (flags & 0x10u) != 0u;
    size_t n = 0u;
    magcal_optics_cfg_t oc;
    magcal_status_t st, st2;

    while (n < FZ_N && fuzz_left(&in) >= (as_int16 ? 4u : 8u)) {
        if (as_int16) {
            int16_t xi = (int16_t)fuzz_u16(&in);
            int16_t yi = (int16_t)fuzz_u16(&in);
            fz_pts[n].x = (float)xi * scale;
            fz_pts[n].y = (float)yi * scale;
        } else {
            fz_pts[n].x = fuzz_f32(&in);
            fz_pts[n].y = fuzz_f32(&in);
        }
        ++n;
    }

    /* OPTICS: the same input through all four implementations must agree bit for bit */
    oc.eps = eps;
    oc.eps_prime = eps_prime;
    oc.min_pts = min_pts;
    oc.order = (magcal_optics_order_t)(flags & 3u);
    oc.neighbors = (magcal_neighbors_t)((flags >> 2) & 3u);
    st = fz_optics(&oc, n, 0);
    if (st == MAGCAL_OK) {
        uint16_t n_cl = 0u;
        magcal_optics_cfg_t alt = oc;
        alt.order = oc.order == MAGCAL_OPTICS_CLASSIC ? MAGCAL_OPTICS_IMPROVED : MAGCAL_OPTICS_CLASSIC;
        st2 = fz_optics(&alt, n, 1);
        FUZZ_CHECK(st2 == MAGCAL_OK, "other ordering failed");
        fz_same(n, "CLASSIC and IMPROVED differ");
        alt = oc;
        alt.neighbors = oc.neighbors == MAGCAL_NEIGHBORS_GRID ? MAGCAL_NEIGHBORS_BRUTE : MAGCAL_NEIGHBORS_GRID;
        st2 = fz_optics(&alt, n, 1);
        FUZZ_CHECK(st2 == MAGCAL_OK, "other neighbour search failed");
        fz_same(n, "BRUTE and GRID differ");

        (void)memset(fz_labels, 0x77, sizeof fz_labels);
        st2 = magcal_optics_extract_dbscan(fz_order[0], fz_reach[0], fz_core[0], n, eps, eps_prime,
                                           fz_labels, &n_cl);
        FUZZ_CHECK(st2 == MAGCAL_OK || st2 == MAGCAL_ERR_ARG, "extract status");
        if (st2 == MAGCAL_OK) {
            fz_labels_ok(fz_labels, n, n_cl);
            fz_largest(fz_labels, n);
        } else {
            FUZZ_CHECK(fz_labels[0] == 0x7777, "extract wrote labels on failure");
        }
    } else if (st == MAGCAL_ERR_NONFINITE) {
        FUZZ_CHECK(!fz_all_finite(n), "NONFINITE for finite points");
    }

    /* one-call filter: explicit parameters as given, and automatic (eps <= 0) */
    {
        magcal_optics_result_t info;
        size_t i;
        magcal_status_t sf;
        (void)memset(fz_mask, 9, n);
        sf = magcal_optics_filter(&oc, fz_pts, n, fz_work, sizeof fz_work, fz_mask, &info);
        FUZZ_CHECK(fuzz_status_known(sf) && sf != MAGCAL_ERR_NULL && sf != MAGCAL_ERR_WORKSPACE,
                   "filter status");
        for (i = 0u; i < n; ++i) {
            FUZZ_CHECK(sf == MAGCAL_OK ? fz_mask[i] <= 1u : fz_mask[i] == 9u, "filter mask");
        }
        if (sf == MAGCAL_OK) {
            size_t k = 0u;
            for (i = 0u; i < n; ++i) {
                k += fz_mask[i];
            }
            FUZZ_CHECK(k == info.n_inliers && k >= 1u, "filter inlier count");
            FUZZ_CHECK(info.eps_prime > 0.0f && info.eps_prime <= info.eps, "filter eps'");
        }
        oc.eps = 0.0f;
        (void)memset(fz_mask, 9, n);
        sf = magcal_optics_filter(&oc, fz_pts, n, fz_work, sizeof fz_work, fz_mask, &info);
        FUZZ_CHECK(sf == MAGCAL_OK || sf == MAGCAL_ERR_TOO_FEW_POINTS || sf == MAGCAL_ERR_NONFINITE ||
                       sf == MAGCAL_ERR_DEGENERATE || sf == MAGCAL_ERR_ALL_NOISE ||
                       sf == MAGCAL_ERR_ARG,
                   "auto filter status");
        if (sf == MAGCAL_OK) {
            FUZZ_CHECK(isfinite(info.eps_prime) && info.eps_prime > 0.0f, "auto eps'");
        }
    }

    /* DBSCAN with the fuzzed eps / MinPts; grid and brute must agree */
    {
        magcal_dbscan_cfg_t dc;
        uint16_t n_cl = 0u, n_cl2 = 0u;
        dc.eps = eps;
        dc.min_pts = min_pts;
        dc.neighbors = (magcal_neighbors_t)((flags >> 2) & 3u);
        (void)memset(fz_labels, 0x77, sizeof fz_labels);
        st = magcal_dbscan_run(&dc, fz_pts, n, fz_work, sizeof fz_work, fz_labels, &n_cl, NULL);
        FUZZ_CHECK(st == MAGCAL_OK || st == MAGCAL_ERR_ARG || st == MAGCAL_ERR_TOO_FEW_POINTS ||
                       st == MAGCAL_ERR_NONFINITE,
                   "dbscan status");
        if (st == MAGCAL_OK) {
            fz_labels_ok(fz_labels, n, n_cl);
            dc.neighbors = dc.neighbors == MAGCAL_NEIGHBORS_GRID ? MAGCAL_NEIGHBORS_BRUTE : MAGCAL_NEIGHBORS_GRID;
            st2 = magcal_dbscan_run(&dc, fz_pts, n, fz_work, sizeof fz_work, fz_labels2, &n_cl2, NULL);
            FUZZ_CHECK(st2 == MAGCAL_OK && n_cl2 == n_cl &&
                           memcmp(fz_labels, fz_labels2, n * sizeof fz_labels[0]) == 0,
                       "DBSCAN grid and brute differ");
            fz_largest(fz_labels, n);
        } else {
            FUZZ_CHECK(fz_labels[0] == 0x7777, "dbscan wrote labels on failure");
        }
    }

    fz_ellipse(n);
    return 0;
}
