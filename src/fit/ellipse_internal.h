/*
 * Internal header of the 2-D conic fit (src/fit/ellipse*.c, ellipse.h): the power-sum indices, the
 * point source and normalisation of a fit, and the passes each file gives the others. Not
 * installed. Files:
 *   ellipse_fit.c   the normalised least-squares fit: scan, normalisation, Kahan power sums,
 *                   normal equations + LDL^T, conic geometry, RMS residual; the 5-point exact
 *                   path; the one-shot LS fits;
 *   ellipse.c       the public one-shot entry points magcal_ellipse_fit() / _fit_idx();
 *   ellipse_slice.c the time-sliced fit (begin / step) over the same passes;
 *   ellipse_cal.c   ellipse -> calibration (magcal_ellipse_to_cal, kphi, from_conic).
 */
#ifndef MAGCAL_ELLIPSE_INTERNAL_H
#define MAGCAL_ELLIPSE_INTERNAL_H

#include <stddef.h>
#include <stdint.h>

#include "magcal/ellipse.h"
#include "magcal_internal.h"

/* Power sums S_pq = sum x~^p y~^q kept by the accumulator (indices into mom[]). */
#define S10 0u
#define S01 1u
#define S20 2u
#define S11 3u
#define S02 4u
#define S30 5u
#define S21 6u
#define S12 7u
#define S03 8u
#define S31 9u
#define S22 10u
#define S13 11u
#define S04 12u
#define S_COUNT 13u

/* The points a fit uses: pts[idx[k]] for k < n when idx is set, else pts[k] where mask[k] != 0. */
typedef struct {
    const magcal_vec2_t *pts;
    size_t n;
    const uint8_t *mask;
    const uint16_t *idx;
} magcal_efit_src_t;

/* Affine normalisation x~ = (x - mx) * isx, y~ = (y - my) * isy. */
typedef struct {
    float mx;
    float my;
    float isx;
    float isy;
} magcal_efit_norm_t;

/* ---- ellipse_fit.c --------------------------------------------------------------------------- */

/* The points of a masked fit: pts[k] where mask[k] != 0 (mask NULL: every point). */
void magcal_efit_src_masked(magcal_efit_src_t *src, const magcal_vec2_t *pts, size_t n,
                            const uint8_t *mask);

/* Pass 1 over the points k0..k1-1: number of used points *cnt, finiteness, bounding box (bb = xmin,
 * xmax, ymin, ymax) and the largest magnitude per axis (amax = max|x|, max|y|, for the seed's
 * scaling). bb and amax start at 0 with *cnt = 0. */
magcal_status_t magcal_efit_src_scan_range(const magcal_efit_src_t *src, size_t k0, size_t k1,
                                           size_t *cnt, float bb[4], float amax[2]);

/* The count rule after pass 1. */
magcal_status_t magcal_efit_scan_count_ok(size_t cnt);

/* Centred normalisation: mid-range of the bounding box, isotropic scale = half its diagonal. */
magcal_status_t magcal_efit_norm_centred(const float bb[4], magcal_efit_norm_t *nm, float *scale);

/* Pass 2 over the points k0..k1-1: power sums of the normalised points into mom (compensation
 * comp; both start at 0), Kahan-compensated unless plain != 0 (the seed's plain float32
 * accumulation, kept only for magcal_ellipse_fit_seed()). */
void magcal_efit_src_moments_range(const magcal_efit_src_t *src, const magcal_efit_norm_t *nm,
                                   int plain, size_t k0, size_t k1, float mom[S_COUNT],
                                   float comp[S_COUNT]);

void magcal_efit_moments_zero(float mom[S_COUNT], float comp[S_COUNT]);

/* Collinear (or nearly) points: smaller covariance eigenvalue below a fraction of the larger.
 * det/tr^2 = l1 l2 / (l1 + l2)^2 is the eigenvalue ratio when that ratio is small. Reads only
 * mom[S10..S02] (the first five entries). */
int magcal_efit_moments_collinear(const float *mom, float cnt);

/* Pass 3 over the points k0..k1-1: sum of squared radial residuals, acc = (sum, compensation). */
void magcal_efit_src_rms_range(const magcal_efit_src_t *src, const float geo[6], size_t k0,
                               size_t k1, float acc[2]);

/*
 * Geometry of x^2 + A xy + B y^2 + C x + D y + E = 0 given in coordinates x~ = (x - mx)/s
 * (isotropic s, so angles are unchanged and lengths scale by s; algorithms.md 2.3) into geo
 * (centre, qform, semi-minor axis: what the residual needs) and, when e is not NULL, into e (every
 * field but residual_rms, min_pivot and n_used). Deterministic: the fits call it once for the
 * residuals and again, once every check has passed, straight into the caller's result (no
 * ellipse-sized temporary on the deepest stack path).
 */
magcal_status_t magcal_efit_conic_geometry(const float coef[5], float mx, float my, float s,
                                           magcal_ellipse_t *e, float geo[6]);

/* Geometry, residual RMS over the cnt used points of src (NULL: RMS 0) and the result in one go
 * (the seed's fit, the 5-point path, magcal_ellipse_from_conic()). */
magcal_status_t magcal_efit_conic_finish(const float coef[5], float mx, float my, float s,
                                         float min_pivot, size_t cnt, const magcal_efit_src_t *src,
                                         magcal_ellipse_t *out);

/* Pass 1 and the centred normalisation, in a frame of their own. */
magcal_status_t magcal_efit_prepare_centred(const magcal_efit_src_t *src, size_t *count,
                                            magcal_efit_norm_t *nm, float *scale);

/*
 * The one-shot least-squares fit: the slice's passes (src_scan_range, src_moments_range,
 * moments_solve, conic_geometry + src_rms_range + conic_store) over every point in one go. Not
 * begin + step(UINT32_MAX): the slice state (216 B on Cortex-M4F) on this frame put the
 * calibrator's run() at 560 B of stack, over its 512-B budget. The sliced fit gives the same
 * result bit for bit (tests/test_ellipse.c, every budget).
 */
magcal_status_t magcal_efit_fit_normal(const magcal_efit_src_t *src, magcal_ellipse_t *out);

/* The 5-point exact fit of the 5 points of src (MAGCAL_NOINLINE: out of magcal_ellipse_fit_idx's
 * frame, which also sits on the deepest path fit_normal -> moments_solve -> magcal_ldlt_solve). */
magcal_status_t magcal_efit_fit_five(const magcal_efit_src_t *src, magcal_ellipse_t *out);

/* ---- ellipse.c ------------------------------------------------------------------------------- */

/* 1 when idx[k0..k1-1] < n_pts (the index check of magcal_ellipse_fit_idx). */
int magcal_efit_idx_in_range(const uint16_t *idx, size_t k0, size_t k1, size_t n_pts);

/* ---- inline at each call site (ellipse_fit.c and ellipse_slice.c), as the static helpers of the
 * one-file original were: GCC inlines them there, so the fits' frames and the deepest stack path
 * (consensus -> fit slice -> 5-point path) stay as measured. ---------------------------------- */

/* Normal equations of the rows w = [xy, y^2, x, y, 1], Y = -x^2, solved by equilibrated LDL^T
 * (a: the 5x5 matrix's storage, destroyed; the fit slice lends its scratch, off the stack).
 * On success the coefficients A..E overwrite mom[0..4] (the moments are dead by then; sharing the
 * array keeps the deepest stack path, through magcal_ldlt_solve, short). */
static inline magcal_status_t magcal_efit_moments_solve(float mom[S_COUNT], float cnt, float a[25],
                                          float *min_pivot)
{

    a[0] = mom[S22];
    a[5] = mom[S13];
    a[6] = mom[S04];
    a[10] = mom[S21];
    a[11] = mom[S12];
    a[12] = mom[S20];
    a[15] = mom[S12];
    a[16] = mom[S03];
    a[17] = mom[S11];
    a[18] = mom[S02];
    a[20] = mom[S11];
    a[21] = mom[S02];
    a[22] = mom[S10];
    a[23] = mom[S01];
    a[24] = cnt;
    /* upper triangle is not read by magcal_ldlt_solve; fill it anyway for a defined matrix */
    a[1] = a[5];
    a[2] = a[10];
    a[3] = a[15];
    a[4] = a[20];
    a[7] = a[11];
    a[8] = a[16];
    a[9] = a[21];
    a[13] = a[17];
    a[14] = a[22];
    a[19] = a[23];
    /* right-hand side in mom[0..4], solved in place (no separate b[] on the stack); the order
     * writes each entry after its last read: S20 = mom[2] before mom[2] is replaced */
    mom[4] = -mom[S20];
    mom[0] = -mom[S31];
    mom[1] = -mom[S22];
    mom[2] = -mom[S30];
    mom[3] = -mom[S21];
    return magcal_ldlt_solve(a, mom, 5u, MAGCAL_ELLIPSE_PIVOT_TOL, min_pivot);
}

/* The complete result into out, once the residual RMS is known to be finite (non-finite:
 * residuals of points ~1e19 from the centre overflow): the geometry again, straight into out. */
static inline magcal_status_t magcal_efit_conic_store(const float coef[5], float mx, float my, float s,
                                        float rms, float min_pivot, size_t cnt,
                                        magcal_ellipse_t *out)
{
    float geo[6];
    magcal_status_t st;

    if (!magcal_isfinite_f(rms)) {
        return MAGCAL_ERR_ILL_CONDITIONED;
    }
    st = magcal_efit_conic_geometry(coef, mx, my, s, out, geo);
    if (st == MAGCAL_OK) {
        out->angle_rad = 0.5f * magcal_atan2f(coef[0], 1.0f - coef[1]);
        out->min_pivot = min_pivot;
        out->n_used = (uint16_t)cnt;
        out->residual_rms = rms;
    }
    return st;
}

#endif /* MAGCAL_ELLIPSE_INTERNAL_H */
