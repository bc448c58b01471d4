/**
 * @file ellipse.h
 * @brief Float32-safe 5-parameter least-squares ellipse fit of level magnetometer samples and the
 *        ellipse-to-circle correction (algorithms.md sections 2 and 3).
 *
 * Model: x^2 + A*xy + B*y^2 + C*x + D*y + E = 0, fitted by linear least squares (normal equations,
 * equilibrated LDL^T with a pivot test). The fit is done in NORMALISED coordinates
 *
 *     x~ = (x - norm_center.x) / norm_scale,   y~ = (y - norm_center.y) / norm_scale
 *
 * where norm_center is the mid-range of the used points and norm_scale is half the diagonal of
 * their bounding box (>= the largest distance from norm_center), so |x~|, |y~| <= 1. Centring and
 * scaling keep cond(W^T W) near 20 for a full turn whatever the hard-iron offset (the seed paper's
 * max-abs scaling does not: see magcal_ellipse_fit_seed()). The moments are accumulated in float32
 * with Kahan summation; geometry is extracted in normalised coordinates and mapped back.
 *
 * The fit returns geometry only. Plausibility gates (axis ratio, radius range, arc coverage,
 * residual) belong to the calibrator.
 *
 * Axis conventions: x right, y forward; angles counter-clockwise from +x seen from above (+z);
 * lengths in input units (raw LSB, uT, ...).
 *
 * No workspace is needed: every function works on the caller's sample array in place (read only),
 * with a fixed amount of stack.
 *
 * @code
 * #include "magcal/config.h"   // MAGCAL_MAX_SAMPLES
 * #include "magcal/ellipse.h"
 *
 * static magcal_vec2_t samples[MAGCAL_MAX_SAMPLES];
 *
 * magcal_status_t calibrate(size_t n, magcal_cal2d_t *cal)
 * {
 *     magcal_ellipse_t e;
 *     magcal_status_t st = magcal_ellipse_fit(samples, n, NULL, &e);
 *     if (st != MAGCAL_OK) {
 *         return st;                      // keep the previous calibration
 *     }
 *     // gate e.semi_major / e.semi_minor, e.residual_rms, ... here, then:
 *     return magcal_ellipse_to_cal(&e, MAGCAL_CORR_SYMMETRIC, 0.0f, cal);
 * }
 * @endcode
 */
#ifndef MAGCAL_ELLIPSE_H
#define MAGCAL_ELLIPSE_H

#include <stddef.h>
#include <stdint.h>

#include "magcal/heading.h"
#include "magcal/status.h"
#include "magcal/types.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Smallest number of points of a fit (5 unknowns). */
#define MAGCAL_ELLIPSE_MIN_POINTS 5u

/** Largest number of points of one fit (n_used is a uint16_t). */
#define MAGCAL_ELLIPSE_MAX_POINTS 65535u

/* Numerical tolerances MAGCAL_ELLIPSE_PIVOT_TOL, MAGCAL_ELLIPSE_PARABOLA_TOL and
 * MAGCAL_ELLIPSE_COLLINEAR_TOL are build-time settings in magcal/config.h. */

/** Fitted ellipse. Lengths and centre in input units; see the file comment for normalisation. */
typedef struct {
    /** centre (x0, y0) = hard-iron estimate, input units */
    magcal_vec2_t center;
    /** r1 <= r2, input units */
    float semi_minor;
    /** r2, input units */
    float semi_major;
    /** theta: direction of the semi-MINOR axis e1 = (cos, sin), in (-pi/2, pi/2] (alg. 2.3) */
    float angle_rad;
    /** A..E in NORMALISED coordinates (x~, y~) */
    float coef[5];
    /** provisional centre used for normalisation, input units */
    magcal_vec2_t norm_center;
    /** scale s used for normalisation, input units */
    float norm_scale;
    /** RMS of magcal_ellipse_residual() over the used points, input units */
    float residual_rms;
    /** smallest equilibrated LDL^T pivot (5-point exact path: smallest |U_jj|) */
    float min_pivot;
    /** (q11, q12, q22): (p - c)^T Q (p - c) = 1 on the ellipse, input units^-2 */
    float qform[3];
    /** number of points used */
    uint16_t n_used;
} magcal_ellipse_t;

/**
 * Correction form built by magcal_ellipse_to_cal() (algorithms.md 2.4; docs/ellipse.md).
 *
 * Every form maps the ellipse onto a circle; they differ only by a rotation, i.e. a constant heading
 * offset, so the right one is the one whose distortion model matches the hardware:
 * - SYMMETRIC (and KX1) assume a symmetric soft iron T = P (no rotation of its own);
 * - KPHI assumes the source documents' model Hm = K Phi_p H + b (OPTICS ellipse paper eq. 8 and
 *   the compass-swing article, installation rotation phi_s = 0, kx = 1), see magcal_ellipse_kphi().
 * Under the documents' model the symmetric forms leave beta = atan2((ky - 1) sin phi_p,
 * (1 + ky) cos phi_p) (magcal_ellipse_kphi_t::beta_rad); under a symmetric soft iron KPHI leaves
 * -beta. Neither sees the installation rotation (swing coefficient A does).
 */
typedef enum {
    /** M = rho R(theta) diag(1/r1, 1/r2) R(theta)^T (whitening, default) */
    MAGCAL_CORR_SYMMETRIC = 0,
    /** the symmetric form scaled to the semi-minor radius: M = R diag(1, r1/r2) R^T (= r1 M_sym).
     *  NOT the documents' "kx = 1" form (that is MAGCAL_CORR_KPHI); the name is historical. */
    MAGCAL_CORR_KX1 = 1,
    /** upper triangular M (the y axis keeps its direction) */
    MAGCAL_CORR_TRIANGULAR = 2,
    /** the source documents' form: M = rho/h_x (K Phi_p)^-1, K = diag(1, ky) (kx = 1),
     *  Phi_p = [[cos phi_p, sin phi_p], [sin phi_p, cos phi_p]], in the library's axes */
    MAGCAL_CORR_KPHI = 3
} magcal_corr_form_t;

/** Largest valid magcal_corr_form_t value (for range checks of stored configurations). */
#define MAGCAL_CORR_LAST MAGCAL_CORR_KPHI

/**
 * The source documents' error coefficients of an ellipse (the hypothesis Hm = K Phi_p H + b with
 * the installation rotation phi_s = 0 and kx = 1; algorithms.md 1.3 with T = K Phi_p).
 *
 * Axes are the library's (x right, y forward), which are the OPTICS ellipse paper's axes. The
 * compass-swing article writes its model in x-forward axes (Hx = H0 cos phi); the same hardware
 * there has ky_article = 1/ky and the same phi_p.
 */
typedef struct {
    /** ky / kx: y-axis sensitivity relative to the x axis (only the ratio is observable) */
    float ky;
    /** phi_p: non-orthogonality / soft-iron angle, radians, in (-pi/4, pi/4) */
    float phi_p_rad;
    /** H0 kx: the horizontal field as the x axis sees it (= the ellipse's half-width in x),
     *  input units; the default output radius of MAGCAL_CORR_KPHI */
    float h_x;
    /** heading(SYMMETRIC) - heading(KPHI) for the same sample, radians:
     *  atan2((ky - 1) sin phi_p, (1 + ky) cos phi_p) */
    float beta_rad;
    /** hard iron (bx, by) = the ellipse centre, input units */
    magcal_vec2_t b;
} magcal_ellipse_kphi_t;

/**
 * @brief Least-squares ellipse fit of the points selected by mask (normalised, float32 safe).
 * @param[in]  pts  samples, x right, y forward, any unit; |values| up to about 1e15.
 * @param[in]  n    number of entries in pts (and mask), <= 65535 when mask is NULL.
 * @param[in]  mask NULL = use every point; else use pts[i] where mask[i] != 0.
 * @param[out] out  result; untouched on failure.
 * @return MAGCAL_OK;
 *         MAGCAL_ERR_NULL (pts or out NULL);
 *         MAGCAL_ERR_ARG (more than MAGCAL_ELLIPSE_MAX_POINTS used points);
 *         MAGCAL_ERR_TOO_FEW_POINTS (fewer than 5 used points);
 *         MAGCAL_ERR_NONFINITE (a used point is NaN/Inf);
 *         MAGCAL_ERR_DEGENERATE (all used points identical, or collinear);
 *         MAGCAL_ERR_ILL_CONDITIONED (pivot below MAGCAL_ELLIPSE_PIVOT_TOL: too little rotation,
 *         points on a degenerate conic; or finite points whose x or y range exceeds FLT_MAX,
 *         or whose residuals overflow float32: about 1.8e19 from the centre);
 *         MAGCAL_ERR_HYPERBOLA (4B - A^2 < 0: arc too short, outliers, tilt);
 *         MAGCAL_ERR_PARABOLA (|4B - A^2| within MAGCAL_ELLIPSE_PARABOLA_TOL);
 *         MAGCAL_ERR_IMAGINARY (K <= 0: imaginary or point ellipse).
 */
magcal_status_t magcal_ellipse_fit(const magcal_vec2_t *pts, size_t n, const uint8_t *mask,
                                   magcal_ellipse_t *out);

/**
 * @brief Fit the subset pts[idx[0..m-1]] (e.g. a RANSAC minimal set).
 *
 * For m == 5 the conic through the 5 points is solved exactly (Gaussian elimination with partial
 * pivoting on the 5x5 system, no normal equations: cheap, and conditioned on cond(W), not its
 * square); min_pivot is then the smallest |U_jj| of the row-equilibrated LU. For m > 5 this is
 * magcal_ellipse_fit() on the subset.
 * @param[in]  pts   samples.
 * @param[in]  n_pts number of entries in pts (every idx[k] must be < n_pts).
 * @param[in]  idx   indices of the points to use (duplicates give MAGCAL_ERR_DEGENERATE).
 * @param[in]  m     number of indices, 5..MAGCAL_ELLIPSE_MAX_POINTS.
 * @param[out] out   result; untouched on failure.
 * @return as magcal_ellipse_fit(), plus MAGCAL_ERR_NULL (idx NULL) and MAGCAL_ERR_ARG (an index
 *         >= n_pts, or m > MAGCAL_ELLIPSE_MAX_POINTS); MAGCAL_ERR_DEGENERATE for a repeated
 *         index when m == 5.
 */
magcal_status_t magcal_ellipse_fit_idx(const magcal_vec2_t *pts, size_t n_pts, const uint16_t *idx,
                                       size_t m, magcal_ellipse_t *out);

/**
 * Time-sliced least-squares fit (the contract of docs/performance.md "time-sliced work"): the state
 * of one magcal_ellipse_fit() / magcal_ellipse_fit_idx() in caller memory. Fields are private.
 */
typedef struct {
    const magcal_vec2_t *pts_;
    size_t n_;
    const uint8_t *mask_;
    const uint16_t *idx_;
    size_t n_pts_;
    magcal_ellipse_t *out_;
    size_t k_;       /* position of the current pass */
    size_t cnt_;     /* used points (pass 1) */
    float mom_[13];  /* power sums, then A..E in mom_[0..4] */
    float tmp_[25];  /* by pass: bounding box + max |x|, |y| (1); Kahan compensation of mom_ (2);
                      * the 5x5 normal matrix (solve); residual geometry + sum of squares (3) */
    float norm_[5];  /* mx, my, 1/s, 1/s, s */
    float minp_;
    uint32_t used_;  /* estimated M4F instructions charged by the last step (read by consensus.c) */
    uint8_t phase_;
    int8_t status_;
} magcal_ellipse_fit_slice_t;

/**
 * @brief Start a time-sliced magcal_ellipse_fit() (O(1): checks the pointers, stores the inputs).
 * @param[out] s    slice state, caller memory (kept until the fit has finished).
 * @param[in]  pts  as magcal_ellipse_fit(); must stay unchanged until the fit has finished.
 * @param[in]  n    as magcal_ellipse_fit().
 * @param[in]  mask as magcal_ellipse_fit(); must stay unchanged until the fit has finished.
 * @param[out] out  result, written by the last step; untouched on failure.
 * @return MAGCAL_OK (call magcal_ellipse_fit_step()); MAGCAL_ERR_NULL (s, pts or out NULL).
 */
magcal_status_t magcal_ellipse_fit_begin(magcal_ellipse_fit_slice_t *s, const magcal_vec2_t *pts,
                                         size_t n, const uint8_t *mask, magcal_ellipse_t *out);

/**
 * @brief Start a time-sliced magcal_ellipse_fit_idx() (O(1); the index range is checked by the
 *        steps).
 * @return MAGCAL_OK; MAGCAL_ERR_NULL (s, pts, idx or out NULL); MAGCAL_ERR_ARG
 *         (m > MAGCAL_ELLIPSE_MAX_POINTS); MAGCAL_ERR_TOO_FEW_POINTS (m < 5).
 */
magcal_status_t magcal_ellipse_fit_idx_begin(magcal_ellipse_fit_slice_t *s, const magcal_vec2_t *pts,
                                             size_t n_pts, const uint16_t *idx, size_t m,
                                             magcal_ellipse_t *out);

/**
 * @brief Do at most about budget Cortex-M4F instructions of the fit started by
 *        magcal_ellipse_fit_begin() or magcal_ellipse_fit_idx_begin() (at least one unit of work,
 *        so every budget >= 1 makes progress).
 * @param[in,out] s      slice state.
 * @param[in]     budget estimated M4F instructions for this call.
 * @return MAGCAL_IN_PROGRESS while work remains; then exactly the status of the one-shot call
 *         (and *out bit for bit), returned again by any further call; MAGCAL_ERR_NULL (s NULL);
 *         MAGCAL_ERR_ARG (s not started).
 */
magcal_status_t magcal_ellipse_fit_step(magcal_ellipse_fit_slice_t *s, uint32_t budget);

/**
 * @brief The seed paper's variant: max-abs scaling only (x~ = x/max|x|, y~ = y/max|y|, no
 *        centring), coefficients mapped back to input units, geometry extracted there.
 *
 * Kept for comparison tests and documentation: with a hard-iron offset much larger than the
 * radius it loses accuracy (offset/radius 5 at 25000 counts) and positive definiteness
 * (offset/radius 20). Like the seed it accumulates plain float32 sums (no Kahan); the solver is
 * the same. Its uncentred moments cannot resolve collinearity, so degenerate inputs may give
 * MAGCAL_ERR_ILL_CONDITIONED instead of MAGCAL_ERR_DEGENERATE. In the result coef[] are in input
 * units (norm_center = 0, norm_scale = 1).
 * @param[in]  pts  samples.
 * @param[in]  n    number of entries.
 * @param[in]  mask NULL or selection mask as in magcal_ellipse_fit().
 * @param[out] out  result; untouched on failure.
 * @return as magcal_ellipse_fit().
 */
magcal_status_t magcal_ellipse_fit_seed(const magcal_vec2_t *pts, size_t n, const uint8_t *mask,
                                        magcal_ellipse_t *out);

/**
 * @brief Geometry of a conic given by its coefficients (the last step of every fit, exposed for
 *        fits done elsewhere, e.g. a direct ellipse-specific fit, and for tests).
 *
 * The conic x~^2 + A x~y~ + B y~^2 + C x~ + D y~ + E = 0 is given in coordinates
 * x~ = (x - norm_center.x)/norm_scale, y~ = (y - norm_center.y)/norm_scale (use {0,0} and 1 for
 * input units). Note: a least-squares fit cannot return K < 0 in exact arithmetic (E is free, so
 * the algebraic residuals have zero mean); MAGCAL_ERR_IMAGINARY from a fit means rounding on a
 * point-like data set.
 * @param[in]  coef        A..E.
 * @param[in]  norm_center normalisation centre, input units.
 * @param[in]  norm_scale  normalisation scale, > 0.
 * @param[out] out         geometry, coef, norm_*, qform set; residual_rms = 0, n_used = 0,
 *                         min_pivot = 1. Untouched on failure.
 * @return MAGCAL_OK; MAGCAL_ERR_NULL; MAGCAL_ERR_NONFINITE (an input is NaN/Inf);
 *         MAGCAL_ERR_ARG (norm_scale <= 0); MAGCAL_ERR_HYPERBOLA; MAGCAL_ERR_PARABOLA;
 *         MAGCAL_ERR_IMAGINARY (K <= 0); MAGCAL_ERR_ILL_CONDITIONED (geometry over/underflows).
 */
magcal_status_t magcal_ellipse_from_conic(const float coef[5], magcal_vec2_t norm_center,
                                          float norm_scale, magcal_ellipse_t *out);

/**
 * @brief Signed approximate geometric distance of p to the ellipse, input units.
 *
 * Radial distance along the ray from the centre: |u| - rho(u) with u = p - center and rho(u) the
 * ellipse's radius in the direction of u, i.e. |u| * (1 - 1/sqrt(u^T Q u)). Positive outside,
 * negative inside, exact for a circle; -semi_minor at the centre. Cost: 2 sqrt + 1 division.
 * @param[in] e ellipse from a successful fit (not checked beyond NULL).
 * @param[in] p sample.
 * @return the distance; NaN when e is NULL or p is non-finite.
 */
float magcal_ellipse_residual(const magcal_ellipse_t *e, magcal_vec2_t p);

/**
 * @brief Build the correction h = M (raw - center) mapping the ellipse onto a circle.
 *
 * All forms differ only by a rotation, i.e. a constant heading offset (algorithms.md 1.3, 2.4).
 * Output radius (stored in out->radius):
 * - MAGCAL_CORR_SYMMETRIC: rho if rho > 0, else the geometric mean sqrt(r1 r2) (input units);
 * - MAGCAL_CORR_KX1: rho > 0 gives rho (then M equals the symmetric form), else r1
 *   (R diag(1, r1/r2) R^T);
 * - MAGCAL_CORR_TRIANGULAR: rho if rho > 0, else sqrt(r1 r2);
 * - MAGCAL_CORR_KPHI: rho if rho > 0, else h_x of magcal_ellipse_kphi() (then M = (K Phi_p)^-1
 *   exactly, the documents' inverse with kx = 1).
 * @param[in]  e    ellipse from a successful fit (its axes, centre and qform are used: the axis
 *                  direction is the eigenvector of qform, the direction angle_rad describes).
 * @param[in]  form correction form.
 * @param[in]  rho  output radius (e.g. 1, or H0 from the geomagnetic model), or <= 0 (see above).
 * @param[out] out  calibration (magic set); untouched on failure.
 * @return MAGCAL_OK; MAGCAL_ERR_NULL; MAGCAL_ERR_ARG (unknown form, or e not a valid ellipse:
 *         non-positive or non-finite axes, r1 > r2); MAGCAL_ERR_NONFINITE (rho NaN/Inf).
 */
magcal_status_t magcal_ellipse_to_cal(const magcal_ellipse_t *e, magcal_corr_form_t form, float rho,
                                      magcal_cal2d_t *out);

/**
 * @brief The source documents' error coefficients (ky, phi_p, hard iron) of a fitted ellipse.
 *
 * Inverts the ellipse's quadratic form Q ~ (K Phi_p^2 K)^-1: ky = sqrt(q11/q22),
 * sin 2phi_p = -q12 / sqrt(q11 q22). Every ellipse has exactly one such (ky > 0, |phi_p| < 45 deg).
 * @param[in]  e   ellipse from a successful fit.
 * @param[out] out coefficients; untouched on failure.
 * @return MAGCAL_OK; MAGCAL_ERR_NULL; MAGCAL_ERR_ARG (e not a valid ellipse, as in
 *         magcal_ellipse_to_cal()).
 */
magcal_status_t magcal_ellipse_kphi(const magcal_ellipse_t *e, magcal_ellipse_kphi_t *out);

#ifdef __cplusplus
}
#endif

#endif /* MAGCAL_ELLIPSE_H */
