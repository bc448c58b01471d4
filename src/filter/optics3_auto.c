/*
 * The automatic parameters of the 3-D OPTICS stage (optics.h "Automatic parameters", docs/optics.md
 * "3-D"; optics3_internal.h): robust centre and radius with clump thinning, one ordering at
 * eps = R (optics3_order.c), the eps' rule over the stored ordering, magcal_optics_auto_params3.
 */
#include <math.h>
#include <string.h>

#include "magcal/optics.h"
#include "magcal_internal.h"
#include "neighbors.h"

#if MAGCAL_CFG_ENABLE_3D /* whole file: config.h feature switch (optics_core.h inside) */
#include "optics3_internal.h"


/* The record behind the run's workspace (pointer-aligned inside the 4-aligned workspace; the
 * caller has checked work_len >= MAGCAL_OPTICS3_FILTER_WORKSPACE_LEN(n) before it is written). */
magcal_o3_auto_t *magcal_o3_auto_record(uint8_t *w, size_t n)
{
    uint8_t *p = w + MAGCAL_OPTICS3_FILTER_RUN_OFFSET_(n) + MAGCAL_OPTICS3_WORKSPACE_LEN(n);
    const size_t mis = magcal_misalign(p, sizeof(void *));
    return (magcal_o3_auto_t *)(void *)(p + ((mis == 0u) ? 0u : (sizeof(void *) - mis)));
}

/* Copy coordinate `axis` (0 x, 1 y, 2 z) of the counted points (use == NULL: all; else bit i of
 * use set) within sqrt(lim2) of c (all when lim2 is infinite) into a; returns how many. */
static size_t gather3(const magcal_vec3_t *pts, size_t n, const uint8_t *use,
                      const magcal_vec3_t *c, float lim2, unsigned axis, float *a)
{
    size_t i;
    size_t k = 0u;
    for (i = 0; i < n; ++i) {
        if ((use == NULL || ((unsigned)use[i >> 3] & (1u << (i & 7u))) != 0u) &&
            (lim2 == INFINITY || magcal_o3_dist2(&pts[i], c) <= lim2)) {
            a[k] = axis == 0u ? pts[i].x : (axis == 1u ? pts[i].y : pts[i].z);
            ++k;
        }
    }
    return k;
}

/*
 * Robust centre and radius over the counted points (bits of use, NULL = all): coordinate
 * medians, R = median distance; passes after the first use only the points within AUTO3_TRIM R
 * of the previous centre (a far cluster cannot drag the centre). a: float[n] scratch.
 */
static magcal_status_t robust_centre3(const magcal_vec3_t *pts, size_t n, const uint8_t *use,
                                      float *a, magcal_vec3_t *cen_out, float *rad_out)
{
    magcal_vec3_t cen = {0.0f, 0.0f, 0.0f};
    float rad = INFINITY;
    size_t i;
    unsigned pass;
    for (pass = 0; pass <= AUTO3_TRIM_PASSES; ++pass) {
        const float lim2 = pass == 0u ? INFINITY : (AUTO3_TRIM * rad) * (AUTO3_TRIM * rad);
        magcal_vec3_t nc;
        size_t k = gather3(pts, n, use, &cen, lim2, 0u, a);
        if (k < AUTO3_MIN_N) {
            break; /* keep the previous estimate */
        }
        nc.x = magcal_ocore_select_kth(a, k, k / 2u);
        (void)gather3(pts, n, use, &cen, lim2, 1u, a);
        nc.y = magcal_ocore_select_kth(a, k, k / 2u);
        (void)gather3(pts, n, use, &cen, lim2, 2u, a);
        nc.z = magcal_ocore_select_kth(a, k, k / 2u);
        k = 0u;
        for (i = 0; i < n; ++i) {
            if ((use == NULL || ((unsigned)use[i >> 3] & (1u << (i & 7u))) != 0u) &&
                (lim2 == INFINITY || magcal_o3_dist2(&pts[i], &cen) <= lim2)) {
                a[k] = sqrtf(magcal_o3_dist2(&pts[i], &nc));
                ++k;
            }
        }
        cen = nc;
        rad = magcal_ocore_select_kth(a, k, k / 2u);
        if (!(rad > 0.0f) || !magcal_isfinite_f(rad) || magcal_nbr_eps_ok(rad) == 0) {
            return MAGCAL_ERR_DEGENERATE;
        }
    }
    if (rad == INFINITY) {
        return MAGCAL_ERR_DEGENERATE;
    }
    *cen_out = cen;
    *rad_out = rad;
    return MAGCAL_OK;
}

/* Median distance of AUTO3_PAIRS pseudo-random pairs: a scale a clump of up to 70 % of the
 * samples cannot shrink (a pair falls inside one clump with probability f^2). */
static float pair_scale3(const magcal_vec3_t *pts, size_t n, float *a)
{
    uint32_t state = AUTO3_SEED;
    size_t k;
    const size_t m = n < AUTO3_PAIRS ? n : AUTO3_PAIRS;
    /* cppcheck-suppress knownConditionTrueFalse ; false positive: m = min(n, pairs) >= 16 (check_points) */
    for (k = 0; k < m; ++k) {
        const size_t i = (size_t)(magcal_ocore_rand(&state) % (uint32_t)n);
        const size_t j = (size_t)(magcal_ocore_rand(&state) % (uint32_t)n);
        a[k] = sqrtf(magcal_o3_dist2(&pts[i], &pts[j]));
    }
    return magcal_ocore_select_kth(a, m, m / 2u);
}

/* Cell side factor for n samples: 1 up to AUTO3_THIN_N, then sqrt(AUTO3_THIN_N / n) (a shell
 * has (4 pi R^2) / h^2 cells: the shell keeps its majority of representatives at every n). */
static float thin_scale3(size_t n)
{
    return n > AUTO3_THIN_N ? sqrtf((float)AUTO3_THIN_N / (float)n) : 1.0f;
}

/* Cell coordinate of v / h, clamped to +-AUTO3_CELL_HALF (far points share the border cells). */
static float cell3(float v, float h)
{
    const float lim = (float)AUTO3_CELL_HALF;
    float u = floorf(v / h);
    u = u < -lim ? -lim : (u > lim - 1.0f ? lim - 1.0f : u);
    return u + lim;
}

/*
 * Thinning: one representative (lowest index) per cubic cell of side h around c, as bits in rep
 * (n/8 bytes), so a rest phase (noise around one point) counts once. key float[n], idx uint16[n]
 * scratch. Returns the number of representatives.
 */
static size_t thin3(const magcal_vec3_t *pts, size_t n, const magcal_vec3_t *c, float h, float *key,
                    uint16_t *idx, uint8_t *rep)
{
    const float side = 2.0f * (float)AUTO3_CELL_HALF;
    size_t i;
    size_t m = 0u;
    for (i = 0; i < n; ++i) {
        key[i] = (cell3(pts[i].x - c->x, h) * side + cell3(pts[i].y - c->y, h)) * side +
                 cell3(pts[i].z - c->z, h);
        idx[i] = (uint16_t)i;
    }
    (void)memset(rep, 0, (n + 7u) / 8u);
    magcal_ocore_sort_idx(idx, key, n);
    for (i = 0; i < n; ++i) {
        if (i == 0u || key[idx[i]] != key[idx[i - 1u]]) {
            const unsigned p = idx[i];
            rep[p >> 3] = (uint8_t)(rep[p >> 3] | (1u << (p & 7u)));
            ++m;
        }
    }
    return m;
}

/* The rule of optics.h. w holds a float[n], b float[n] and the band list uint16[n] (10 n bytes). */
/*
 * Band representatives in the largest cluster of ExtractDBSCAN at eps' (4.3 over the stored ordering):
 * clusters start at a point with reach > eps' and core <= eps' and collect every later point
 * with reach <= eps' (noise points in between do not end them).
 */
static size_t band_in_largest(const magcal_o3_auto_t *au, float eps_prime)
{
    size_t k;
    size_t best = 0u;
    size_t cur = 0u;
    int started = 0;
    for (k = 0; k < au->n; ++k) {
        const size_t p = au->order[k];
        const float d2 = magcal_o3_dist2(&au->pts[p], &au->cen);
        size_t in_band = 0u;
        if (d2 >= au->lo2 && d2 <= au->hi2 &&
            ((unsigned)au->rep[p >> 3] & (1u << (p & 7u))) != 0u) {
            in_band = 1u; /* a representative in the band: a rest phase counts once */
        }
        if (au->reach[p] > eps_prime) {
            if (au->core[p] <= eps_prime) {
                best = cur > best ? cur : best;
                cur = in_band;
                started = 1;
            }
        } else if (started != 0) {
            cur += in_band;
        } else {
            /* not reached: the first point has reach = inf */
        }
    }
    return cur > best ? cur : best;
}

/*
 * The rule of optics.h: robust centre and R, one OPTICS run with eps = R (ordering, reach and
 * core stored in w), then the smallest eps' (geometric bisection over [R/256, R], 20 steps:
 * 5e-6 relative) whose largest cluster holds 75 % of the shell band, times AUTO3_SAFETY.
 * Layout of w: reach float[n] | core float[n] | order uint16[n] | run workspace.
 */
/* (use: the caller's copy of the configuration, changed here) */
magcal_status_t magcal_o3_auto_run(magcal_optics_cfg_t *use, const magcal_vec3_t *pts, size_t n,
                                 uint8_t *w, magcal_o3_auto_t *au)
{
    float *a = (float *)(void *)w;
    magcal_vec3_t cen = {0.0f, 0.0f, 0.0f};
    magcal_o3_ctx_t *c;
    float rad = INFINITY;
    float lo;
    float hi;
    float e;
    float h;
    size_t i;
    size_t m = 0u;
    size_t target;
    unsigned round;
    int have;
    /* thinning scratch before the run: key float[n] | idx uint16[n] | rep bits; after the run in
     * the run's workspace (free again), where rep survives the bisection */
    uint8_t *rw = w + MAGCAL_OPTICS3_FILTER_RUN_OFFSET_(n);
    uint8_t *rep = rw + 6u * n;

    /* centre and radius with each rest phase (noise around one point) counted once: cells of
     * a fraction of the pair scale first (a clump cannot shrink it), then of the radius found */
    h = pair_scale3(pts, n, a) * AUTO3_THIN_PAIR; /* coarse: out of any clump first */
    if (!(h > 0.0f) || !magcal_isfinite_f(h)) {
        return MAGCAL_ERR_DEGENERATE;
    }
    have = 0;
    if (robust_centre3(pts, n, NULL, a, &cen, &rad) == MAGCAL_OK) {
        have = 1;
    }
    if (have == 0) {
        cen = pts[0]; /* more than half the samples identical: the first grid's origin */
    }
    for (round = 0u; round < AUTO3_THIN_ROUNDS; ++round) {
        if (thin3(pts, n, &cen, h, (float *)(void *)rw, (uint16_t *)(void *)(rw + 4u * n), rep) >=
                AUTO3_MIN_N &&
            robust_centre3(pts, n, rep, a, &cen, &rad) == MAGCAL_OK) {
            have = 1;
            h = rad * AUTO3_THIN_REL * thin_scale3(n);
        }
    }
    if (have == 0) {
        return MAGCAL_ERR_DEGENERATE;
    }
    lo = rad - AUTO3_BAND * rad;
    hi = rad + AUTO3_BAND * rad;
    au->pts = pts;
    au->n = n;
    au->cen = cen;
    au->rad = rad;
    au->lo2 = lo * lo;
    au->hi2 = hi * hi;
    for (i = 0; i < n; ++i) {
        const float d2 = magcal_o3_dist2(&pts[i], &cen);
        m += (d2 >= au->lo2 && d2 <= au->hi2) ? 1u : 0u;
    }
    if (m < AUTO3_MIN_BAND) {
        return MAGCAL_ERR_DEGENERATE;
    }
    /* the ordering at eps = R holds every extraction at eps' <= R */
    use->eps = AUTO3_MAX_REL * rad;
    use->min_pts = (uint16_t)AUTO3_MIN_PTS;
    /* at eps = R the 3x3x3 block covers the whole shell: the brute search, whose reach pass
     * shrinks with the unprocessed list, is cheaper (filter at n = 1000: 43.7 M -> 36.7 M) */
    use->neighbors = MAGCAL_NEIGHBORS_BRUTE;
    c = magcal_o3_ctx_setup(use, pts, n, w + MAGCAL_OPTICS3_FILTER_RUN_OFFSET_(n));
    c->oc.reach = (float *)(void *)w;
    c->oc.core = (float *)(void *)(w + 4u * n);
    c->oc.order = (uint16_t *)(void *)(w + 8u * n);
    au->reach = c->oc.reach;
    au->core = c->oc.core;
    au->order = c->oc.order;
    magcal_o3_loop(c);
    au->neighbors = c->use_grid != 0 ? MAGCAL_NEIGHBORS_GRID : MAGCAL_NEIGHBORS_BRUTE;
    au->eps = use->eps;
    /* the representatives again (the run used this memory), counted in the band */
    (void)thin3(pts, n, &cen, rad * AUTO3_THIN_REL * thin_scale3(n), (float *)(void *)rw,
                (uint16_t *)(void *)(rw + 4u * n), rep);
    au->rep = rep;
    m = 0u;
    for (i = 0; i < n; ++i) {
        const float d2 = magcal_o3_dist2(&pts[i], &cen);
        if (d2 >= au->lo2 && d2 <= au->hi2 && ((unsigned)rep[i >> 3] & (1u << (i & 7u))) != 0u) {
            ++m;
        }
    }

    target = m - m / 4u; /* 75 % of the band */
    lo = AUTO3_MIN_REL * rad;
    hi = AUTO3_MAX_REL * rad;
    if (band_in_largest(au, hi) < target) {
        e = hi; /* the bulk never connects within R: keep the largest cluster at R */
    } else if (band_in_largest(au, lo) >= target) {
        e = lo;
    } else {
        for (i = 0; i < AUTO3_BISECT; ++i) { /* invariant: lo fails, hi connects */
            const float mid = sqrtf(lo * hi);
            if (band_in_largest(au, mid) >= target) {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        e = AUTO3_SAFETY * hi;
    }
    if (e > AUTO3_MAX_REL * rad) {
        e = AUTO3_MAX_REL * rad;
    }
    au->eps_prime = e;
    return MAGCAL_OK;
}

magcal_status_t magcal_optics_auto_params3(const magcal_vec3_t *pts, size_t n, void *work,
                                           size_t work_len, float *eps, uint16_t *min_pts,
                                           float *eps_prime)
{
    magcal_optics_cfg_t cfg = MAGCAL_OPTICS_CFG_DEFAULT;
    magcal_status_t st;
    magcal_o3_auto_t *au;
    if (pts == NULL || work == NULL || eps == NULL || min_pts == NULL || eps_prime == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (magcal_misalign(work, 4u) != 0u) {
        return MAGCAL_ERR_ALIGNMENT;
    }
    st = magcal_o3_check_points(pts, n, AUTO3_MIN_N);
    if (st != MAGCAL_OK) {
        return st;
    }
    if (work_len < MAGCAL_OPTICS3_FILTER_WORKSPACE_LEN(n)) {
        return MAGCAL_ERR_WORKSPACE;
    }
    au = magcal_o3_auto_record((uint8_t *)work, n);
    st = magcal_o3_auto_run(&cfg, pts, n, (uint8_t *)work, au);
    if (st != MAGCAL_OK) {
        return st;
    }
    *eps = au->eps;
    *eps_prime = au->eps_prime;
    *min_pts = (uint16_t)AUTO3_MIN_PTS;
    return MAGCAL_OK;
}


#endif /* MAGCAL_CFG_ENABLE_3D */
