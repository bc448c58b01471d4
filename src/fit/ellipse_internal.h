/*
 * Internal header of the 2-D conic fit (src/fit/ellipse*.c, ellipse.h): the power-sum indices, the
 * point source and normalisation of a fit, and the passes each file gives the others. Not
 * installed. Files:
 *   ellipse_fit.c   the normalised least-squares fit: scan, normalisation, Kahan power sums,
 *                   normal equations + LDL^T, conic geometry, RMS residual; the one-shot LS fits;
 *   ellipse.c       the 5-point exact path and the public one-shot entry points;
 *   ellipse_slice.c the time-sliced fit (begin / step) over the same passes;
 *   ellipse_cal.c   ellipse -> calibration (magcal_ellipse_to_cal, kphi, from_conic).
 */
#ifndef MAGCAL_ELLIPSE_INTERNAL_H
#define MAGCAL_ELLIPSE_INTERNAL_H

#include <stddef.h>
#include <stdint.h>

#include "magcal/ellipse.h"


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

/* Normal equations of the rows w = [xy, y^2, x, y, 1], Y = -x^2, solved by equilibrated LDL^T
 * (a: the 5x5 matrix's storage, destroyed; the fit slice lends its scratch, off the stack).
 * On success the coefficients A..E overwrite mom[0..4] (the moments are dead by then; sharing the
 * array keeps the deepest stack path, through magcal_ldlt_solve, short). */
magcal_status_t magcal_efit_moments_solve(float mom[S_COUNT], float cnt, float a[25],
                                          float *min_pivot);

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

/* The complete result into out, once the residual RMS is known to be finite (non-finite:
 * residuals of points ~1e19 from the centre overflow): the geometry again, straight into out. */
magcal_status_t magcal_efit_conic_store(const float coef[5], float mx, float my, float s,
                                        float rms, float min_pivot, size_t cnt,
                                        magcal_ellipse_t *out);

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

/* ---- ellipse.c ------------------------------------------------------------------------------- */

/* MAGCAL_NOINLINE: keep the 5-point path out of magcal_ellipse_fit_idx's frame, which also sits
 * on the deepest path fit_normal -> moments_solve -> magcal_ldlt_solve. */
magcal_status_t magcal_efit_fit_five(const magcal_efit_src_t *src, magcal_ellipse_t *out);

/* 1 when idx[k0..k1-1] < n_pts (the index check of magcal_ellipse_fit_idx). */
int magcal_efit_idx_in_range(const uint16_t *idx, size_t k0, size_t k1, size_t n_pts);

#endif /* MAGCAL_ELLIPSE_INTERNAL_H */
