/*
 * Coverage of the 3-D fit (azimuth x elevation cells around the centre, ellipsoid.h) and the
 * small public helpers on a 3-D calibration: magcal_ellipsoid_outliers(), _apply(), _coverage().
 */
#include <math.h>
#include <string.h>

#include "ellipsoid_internal.h"

#if MAGCAL_CFG_ENABLE_3D /* whole file: config.h feature switch */

static int cell_of(float x, float y, float z, size_t *cell)
{
    /* tan-free sector boundaries of the azimuth cells: cos / sin of 30, 60, 90, 120, 150 degrees */
    static const float k_bound_c[5] = {0.8660254f, 0.5f, 0.0f, -0.5f, -0.8660254f};
    static const float k_bound_s[5] = {0.5f, 0.8660254f, 1.0f, 0.8660254f, 0.5f};
    float r = magcal_ell_sqrtf(x * x + y * y + z * z);
    float sz;
    float u = -x; /* azimuth measured from -x, as atan2f(y, x) + pi, in [0, 2 pi) */
    float v = -y;
    size_t ia = 0u;
    size_t ie;
    if (!(r > 0.0f)) {
        return 0;
    }
    if (v == 0.0f && u >= 0.0f) { /* as atan2f: (0, 0) -> pi (cell 6), y = 0 < x -> 2 pi (cell 11) */
        ia = (size_t)MAGCAL_ELLIPSOID_COV_AZ / 2u;
        if (u > 0.0f) {
            ia = (size_t)MAGCAL_ELLIPSOID_COV_AZ - 1u;
        }
    } else {
        size_t b;
        if (!(v > 0.0f)) { /* lower half: cells 6..11 */
            u = -u;
            v = -v;
            ia = MAGCAL_ELLIPSOID_COV_AZ / 2u;
        }
        for (b = 0u; b < 5u; ++b) { /* angle >= boundary b: one cell further (no atan2f) */
            if (k_bound_c[b] * v - k_bound_s[b] * u >= 0.0f) {
                ++ia;
            }
        }
    }
    sz = z / r + 1.0f; /* [0, 2]: equal-area bands */
    ie = (size_t)(sz * ((float)MAGCAL_ELLIPSOID_COV_EL / 2.0f));
    if (ie >= MAGCAL_ELLIPSOID_COV_EL) {
        ie = MAGCAL_ELLIPSOID_COV_EL - 1u;
    }
    *cell = ie * MAGCAL_ELLIPSOID_COV_AZ + ia;
    return 1;
}

/* The coverage cells of samples k0..k1-1 around c into bits (samples within tiny of c skipped). */
void magcal_ell_coverage_cells(const magcal_vec3_t *m, size_t k0, size_t k1, const float c[3],
                               float tiny, uint32_t bits[3])
{
    size_t k;
    for (k = k0; k < k1; ++k) {
        size_t cell;
        float x = m[k].x - c[0];
        float y = m[k].y - c[1];
        float z = m[k].z - c[2];
        if (fabsf(x) + fabsf(y) + fabsf(z) <= tiny) {
            continue;
        }
        if (cell_of(x, y, z, &cell) != 0) {
            bits[cell / 32u] |= (uint32_t)1u << (cell % 32u);
        }
    }
}

float magcal_ell_coverage_count(const uint32_t bits[3])
{
    const size_t cells = COV_CELLS;
    size_t k;
    size_t filled = 0u;
    for (k = 0u; k < cells; ++k) {
        if (((bits[k / 32u] >> (k % 32u)) & 1u) != 0u) {
            filled++;
        }
    }
    return (float)filled / (float)cells;
}

static float coverage_of(const magcal_vec3_t *m, size_t n, const float c[3], float tiny)
{
    uint32_t bits[3] = {0u, 0u, 0u};
    magcal_ell_coverage_cells(m, 0u, n, c, tiny, bits);
    return magcal_ell_coverage_count(bits);
}

static int cal_isfinite(const magcal_ellipsoid_cal_t *cal)
{
    size_t i;
    size_t j;
    for (i = 0u; i < 3u; ++i) {
        for (j = 0u; j < 3u; ++j) {
            if (!magcal_isfinite_f(cal->g[i][j])) {
                return 0;
            }
        }
    }
    return magcal_isfinite_f(cal->v.x) && magcal_isfinite_f(cal->v.y) &&
           magcal_isfinite_f(cal->v.z) && magcal_isfinite_f(cal->field);
}

magcal_status_t magcal_ellipsoid_outliers(const magcal_ellipsoid_result_t *res,
                                          const magcal_vec3_t *m, size_t n, uint8_t *outlier,
                                          size_t *n_outliers)
{
    quad_gate_t gate;
    size_t k;
    size_t cnt = 0u;
    if (res == NULL || m == NULL || outlier == NULL || n_outliers == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (n == 0u) {
        return MAGCAL_ERR_TOO_FEW_POINTS;
    }
    if (!magcal_isfinite_f(res->gate_thr) || res->gate_thr < 0.0f ||
        cal_isfinite(&res->gate_cal) == 0) {
        return MAGCAL_ERR_ARG;
    }
    /* validate every sample before writing: outputs stay untouched on failure */
    for (k = 0u; k < n; ++k) {
        if (!magcal_isfinite_f(m[k].x) || !magcal_isfinite_f(m[k].y) ||
            !magcal_isfinite_f(m[k].z)) {
            return MAGCAL_ERR_NONFINITE;
        }
    }
    /* the very predicate the fit accumulated with (gate_keeps), so the counts agree bit for bit */
    gate.cal = (res->gate_thr > 0.0f) ? &res->gate_cal : NULL;
    gate.thr = res->gate_thr;
    for (k = 0u; k < n; ++k) {
        if (magcal_ell_gate_keeps(&gate, &m[k]) != 0) {
            outlier[k] = 0u;
        } else {
            outlier[k] = 1u;
            cnt++;
        }
    }
    *n_outliers = cnt;
    return MAGCAL_OK;
}

magcal_status_t magcal_ellipsoid_apply(const magcal_ellipsoid_cal_t *cal, const magcal_vec3_t *m,
                                       magcal_vec3_t *h)
{
    float r[3];
    size_t i;
    if (cal == NULL || m == NULL || h == NULL) {
        return MAGCAL_ERR_NULL;
    }
    magcal_ell_correct(cal, m, r);
    for (i = 0u; i < 3u; ++i) {
        if (!magcal_isfinite_f(r[i])) {
            return MAGCAL_ERR_NONFINITE;
        }
    }
    h->x = r[0];
    h->y = r[1];
    h->z = r[2];
    return MAGCAL_OK;
}

magcal_status_t magcal_ellipsoid_coverage(const magcal_vec3_t *m, size_t n,
                                          const magcal_vec3_t *centre, float *coverage)
{
    float c[3];
    float mag = 0.0f;
    size_t k;
    if (m == NULL || centre == NULL || coverage == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (n == 0u) {
        return MAGCAL_ERR_TOO_FEW_POINTS;
    }
    if (!magcal_isfinite_f(centre->x) || !magcal_isfinite_f(centre->y) ||
        !magcal_isfinite_f(centre->z)) {
        return MAGCAL_ERR_NONFINITE;
    }
    for (k = 0u; k < n; ++k) {
        float a;
        if (!magcal_isfinite_f(m[k].x) || !magcal_isfinite_f(m[k].y) ||
            !magcal_isfinite_f(m[k].z)) {
            return MAGCAL_ERR_NONFINITE;
        }
        a = fabsf(m[k].x - centre->x) + fabsf(m[k].y - centre->y) + fabsf(m[k].z - centre->z);
        if (a > mag) {
            mag = a;
        }
    }
    c[0] = centre->x;
    c[1] = centre->y;
    c[2] = centre->z;
    *coverage = coverage_of(m, n, c, 1e-6f * mag);
    return MAGCAL_OK;
}

#endif /* MAGCAL_CFG_ENABLE_3D */
