/*
 * Private to the 3-D fit (src/fit/ellipsoid.c: normalisation, normal equations, solvers, outlier gate;
 * src/fit/ellipsoid_trust.c: the trust gates of issue 12). Never installed.
 */
#ifndef MAGCAL_ELLIPSOID_INTERNAL_H
#define MAGCAL_ELLIPSOID_INTERNAL_H

#include <math.h>
#include <stddef.h>

#include "magcal/ellipsoid.h"
#include "magcal_internal.h"

#define MAGCAL_ELL_NQ 10u                                              /* quadric row length */
#define MAGCAL_ELL_NPACK ((MAGCAL_ELL_NQ * (MAGCAL_ELL_NQ + 1u)) / 2u) /* packed lower triangle */
#define MAGCAL_ELL_MAD_TO_SIGMA 1.4826f /* sigma of a normal distribution = 1.4826 x median |r| */

/* Normalisation and Kahan-compensated normal matrix. */
typedef struct {
    float sum[MAGCAL_ELL_NPACK];
    float comp[MAGCAL_ELL_NPACK];
    size_t count;
} quad_acc_t;

/* Samples summed in plain float32 before the block sum is added (Kahan) to the running total:
 * one add per product instead of Kahan's four, the rounding error of a block (32 eps) stays
 * far below the fit's noise while the total keeps Kahan's n-independent error. */
#define MAGCAL_ELL_BLOCK 32u

/* Add the packed block sums `part` (np entries, cleared afterwards) to the Kahan total. */
static inline void magcal_ell_flush(float *sum, float *comp, float *part, size_t np)
{
    size_t p;
    for (p = 0u; p < np; ++p) {
        magcal_kahan_add(&sum[p], &comp[p], part[p]);
        part[p] = 0.0f;
    }
}

/* Optional gate applied while accumulating: keep samples with | |G(m-V)| - F | < thr. */
typedef struct {
    const magcal_ellipsoid_cal_t *cal; /* NULL: keep every sample */
    float thr;
} quad_gate_t;

static inline size_t magcal_ell_pidx(size_t i, size_t j)
{
    /* packed lower triangle, i >= j */
    return (i * (i + 1u)) / 2u + j;
}

/*
 * Square root for the per-sample passes: one VSQRT on a single-precision FPU target (newlib's
 * sqrtf wraps the same instruction in an errno check of about 20 instructions, per call; the fit
 * never reads errno), sqrtf elsewhere. Both are the correctly rounded IEEE square root: identical
 * results, NaN for a negative argument.
 */
static inline float magcal_ell_sqrtf(float x)
{
#if defined(__GNUC__) && defined(__ARM_FP) && ((__ARM_FP & 4) != 0)
    float r;
    __asm__("vsqrt.f32 %0, %1" : "=t"(r) : "t"(x));
    return r;
#else
    return sqrtf(x);
#endif
}

/* h = G (m - V): the correction of one sample. */
static inline void magcal_ell_correct(const magcal_ellipsoid_cal_t *cal, const magcal_vec3_t *m,
                                      float h[3])
{
    float e[3];
    size_t i;
    e[0] = m->x - cal->v.x;
    e[1] = m->y - cal->v.y;
    e[2] = m->z - cal->v.z;
    for (i = 0u; i < 3u; ++i) {
        h[i] = cal->g[i][0] * e[0] + cal->g[i][1] * e[1] + cal->g[i][2] * e[2];
    }
}

static inline float magcal_ell_residual(const magcal_ellipsoid_cal_t *cal, const magcal_vec3_t *m)
{
    float h[3];
    magcal_ell_correct(cal, m, h);
    return magcal_ell_sqrtf(h[0] * h[0] + h[1] * h[1] + h[2] * h[2]) - cal->field;
}

/* The fit's scratch and magcal_ellipsoid_calibrate's result slots hold pointers and size_t: they
 * start at the next multiple of this (a workspace is only promised 4-byte aligned; the 0 or 4
 * bytes of padding are counted in the size macros). */
#define MAGCAL_ELL_ALIGN 8u
static inline uint8_t *magcal_ell_align_up(void *p)
{
    const size_t mis = magcal_misalign(p, MAGCAL_ELL_ALIGN);
    return (uint8_t *)p + ((mis == 0u) ? 0u : (MAGCAL_ELL_ALIGN - mis));
}

/* The trust diagnostics of a fit (copied into the result on success). */
typedef struct {
    float motion_snr;
    float centre_std_rel;
    float shape_std;
    float planarity;
    float field_raw;
} trust_diag_t;

/* Which residual a median is taken of: geometric under `cal`, or (cal NULL) the algebraic
 * residual r.theta - 1 of the 9-parameter quadric `theta` in coordinates (m - mu) * inv_s. */
typedef struct {
    const magcal_ellipsoid_cal_t *cal;
    const float *theta;
    const float *mu;
    float inv_s;
} resid_src_t;

static inline int magcal_ell_gate_keeps(const quad_gate_t *gate, const magcal_vec3_t *m)
{
    if (gate->cal == NULL) {
        return 1;
    }
    return fabsf(magcal_ell_residual(gate->cal, m)) < gate->thr;
}

static inline float magcal_ell_acc_at(const quad_acc_t *acc, size_t i, size_t j)
{
    return (i >= j) ? acc->sum[magcal_ell_pidx(i, j)] : acc->sum[magcal_ell_pidx(j, i)];
}

/* What the motion test needs: the samples, their RMS spread about the mean (raw units), the
 * algebraic-quadric SNR and the provisional sphere (NULL when its fit failed). */
typedef struct {
    const magcal_vec3_t *m;
    size_t n;
    float s;
    float snr_alg;
    const magcal_ellipsoid_cal_t *sphere;
} motion_ctx_t;

/*
 * Per-sample state of the fit in the caller's workspace (magcal_ellipsoid_fit_ws): `res[k]` the
 * residual of sample k under the current fit, `keep[k]` its verdict under the current gate (bit 0;
 * bit 1 holds the next gate's while regate decides). Both NULL (magcal_ellipsoid_fit, no
 * workspace): every pass recomputes them from the samples, with the same float operations, so
 * both give bit-identical results. On MAGCAL_OK `res` holds every sample's residual under the
 * returned calibration (magcal_ellipsoid_calibrate's pre-test reads its largest from there).
 */
struct ell_scratch_s;
typedef struct {
    struct ell_scratch_s *s;
    float *res;
    uint8_t *keep;
} ell_ws_t;

/*
 * The time-sliced fit (docs/calibration_3d.md "Time-sliced fit"): the one-shot algorithm cut into
 * phases. A pass phase visits samples r->k.. while the budget allows (each visit charges its
 * estimated M4F instructions first); a unit phase (a small solve) runs whole when the budget
 * allows. Three sub-machines are entered with a return phase: the residual pass (rp), the median
 * of |r| (med) and the motion SNR (mot); none calls itself, so one return slot each is enough.
 */
/* cppcheck-suppress misra-c2012-5.7 ; deviation D14 (false positive): the enum has no tag; misra.py names every untagged enum alike, so the units that include this header read as one tag declared twice */
enum {
    /* src/fit/ellipsoid.c */
    ELL_PH_CHECK = 0, ELL_PH_N1, ELL_PH_N2, ELL_PH_NORM_DONE, ELL_PH_ACC, ELL_PH_SPHERE,
    ELL_PH_COV, ELL_PH_COV_DONE, ELL_PH_FIT_SOLVE, ELL_PH_FIT_EXTRACT, ELL_PH_KEEP1, ELL_PH_LOOP,
    ELL_PH_LOOP_MED, ELL_PH_THR, ELL_PH_REGATE, ELL_PH_SETTLE, ELL_PH_REFIT, ELL_PH_LOOP_NEXT,
    ELL_PH_FINAL, ELL_PH_FINAL2, ELL_PH_OUT, ELL_PH_RP,
    /* src/fit/ellipsoid_trust.c */
    ELL_PH_ASNR0, ELL_PH_ASNR, ELL_PH_ASNR_DONE, ELL_PH_TG0, ELL_PH_TG1, ELL_PH_INFO,
    ELL_PH_INFO_DONE, ELL_PH_INV, ELL_PH_INV_SUB, ELL_PH_SWM, ELL_PH_SWP, ELL_PH_DIAG, ELL_PH_EXPL0,
    ELL_PH_EXPL1, ELL_PH_MED, ELL_PH_MOT0, ELL_PH_MOT1, ELL_PH_MOT2, ELL_PH_DONE
};
#define ELL_PH_TRUST_FIRST ELL_PH_ASNR0

/* Internal returns of a phase besides a final status (<= 0): go on, or the budget is spent. */
#define ELL_CONT 100
#define ELL_YIELD 101

/* The budget of one step: `left` estimated M4F instructions, `cost` charged so far; the first
 * visit of a step is always allowed (progress for any budget >= 1). */
typedef struct {
    uint32_t left;
    uint32_t cost;
    int first;
} ell_bud_t;

/* Charge one visit of weight w if the budget allows it (always the first of a step). */
static inline int magcal_ell_can(ell_bud_t *b, uint32_t w)
{
    if ((b->cost == 0u && b->first != 0) || (b->cost <= b->left && w <= b->left - b->cost)) {
        b->cost += w;
        return 1;
    }
    return 0;
}

/* Visits of weight w the rest of the budget pays for (at least one on a step's first; at most
 * `left_n`), charged at once: the pass then runs them without a per-visit check. */
static inline size_t magcal_ell_visits(ell_bud_t *b, uint32_t w, size_t left_n)
{
    size_t v = (b->cost <= b->left) ? (size_t)((b->left - b->cost) / w) : 0u;
    if (v == 0u && b->first != 0 && b->cost == 0u) {
        v = 1u;
    }
    if (v > left_n) {
        v = left_n;
    }
    b->cost += (uint32_t)v * w;
    return v;
}

typedef struct { /* residual pass: RMS / count / max |r| under cal of the samples gate keeps */
    const magcal_ellipsoid_cal_t *cal;
    const quad_gate_t *gate;
    ell_ws_t ws;
    float sum;
    float comp;
    float mx;
    size_t cnt;
    float rms; /* results */
    size_t kept;
    uint8_t ret;
} ell_rp_t;

typedef struct { /* median of |r| by histogram refinement (magcal_ell_med_start) */
    const resid_src_t *src;
    const quad_gate_t *gate;
    ell_ws_t ws;
    float lo;
    float hi;
    float width;
    size_t below;
    size_t target;
    float result;
    uint8_t pass;
    uint8_t done;
    uint8_t in_pass;
    uint8_t ret;
} ell_med_t;

typedef struct { /* motion SNR (see motion_snr in ellipsoid_trust.c) */
    float snr_model;
    float limit;
    float snr;
    uint8_t ret;
} ell_mot_t;

typedef struct {
    const magcal_vec3_t *m;
    size_t n;
    const magcal_ellipsoid_cfg_t *cfg;
    ell_ws_t ws;
    magcal_ellipsoid_result_t *out;
    size_t k;          /* position in the current pass */
    uint8_t ph;        /* phase */
    uint8_t rms_valid;
    uint8_t fit_ret;   /* phase after a model fit */
    uint8_t adopt;     /* settle: the next gate's verdicts become the gate's */
    uint8_t sphere;    /* trust gates: the sphere model */
    int8_t stage;      /* trust gates: centre_info's result */
    magcal_status_t pend; /* the failure being explained, the gates' verdict */
    magcal_ellipsoid_model_t model;
    float s;
    float inv_s;
    float coverage;
    float min_pivot;
    float planarity;
    float rms;
    float rmax;
    float gmean;
    size_t iter;
    size_t kept;
    size_t kept_new;
    size_t prev_rejected;
    size_t in_block;   /* accumulations: samples in the open block */
    size_t cnt;        /* trust: samples in the information sums */
    size_t np;
    float comp3[3];    /* normalise: Kahan compensation of the mean */
    float sn[3];       /* trust: sum of the directions */
    uint32_t bits[3];  /* coverage cells */
    float theta[9];    /* the algebraic quadric of the motion test */
    quad_gate_t all;   /* the gate that keeps every sample */
    resid_src_t src_alg;
    resid_src_t src_sph;
    ell_rp_t rp;
    ell_med_t med;
    ell_mot_t mot;
} ell_run_t;

/*
 * The fit's fixed scratch (issue 14: every matrix lives in the caller's workspace, not on the
 * stack): the packed normal matrix, the block sums of the accumulations, one solver matrix (10x10
 * at most), the observability pass's inverse and meat, and the median's histogram.
 */
#define MAGCAL_ELL_INFO_N 9u                                                  /* 3 offset + 6 shape */
#define MAGCAL_ELL_INFO_NPACK ((MAGCAL_ELL_INFO_N * (MAGCAL_ELL_INFO_N + 1u)) / 2u)
#define MAGCAL_ELL_MED_BINS 128u /* histogram bins per pass of the median |residual| */
typedef struct ell_scratch_s {
    quad_acc_t acc;
    float part[MAGCAL_ELL_NPACK];
    float mat[MAGCAL_ELL_NQ * MAGCAL_ELL_NQ];
    float inv[MAGCAL_ELL_INFO_N][MAGCAL_ELL_INFO_N];
    float meat[MAGCAL_ELL_INFO_NPACK];
    uint32_t cnt[MAGCAL_ELL_MED_BINS];
    magcal_ellipsoid_cal_t cal[3]; /* the fit, the gate's fit, the provisional sphere */
    float dir[3][3];               /* the observability pass: scatter of the directions */
    float cc[3][3];                /* its offset covariance */
    float sd[MAGCAL_ELL_INFO_N];   /* its shape variances */
    float vec[2][MAGCAL_ELL_INFO_N]; /* per-term temporaries of the sandwich */
    motion_ctx_t mc;                 /* the fit's state (kept here: off the stack) */
    trust_diag_t dg;
    float mu[3];                     /* normalisation centre */
    float cov_centre[3];             /* centre of the coverage cells */
    float coef[MAGCAL_ELL_NQ];       /* quadric coefficients of the last solve */
    float q3[3][3];                  /* extraction: A_q / k, then destroyed by its square root */
    float e3[3][3];                  /* its eigenvectors */
    float w3[3];                     /* its eigenvalues */
    float h3[3];                     /* one corrected sample (second sandwich pass) */
    quad_gate_t gate;                /* the outlier gate in force */
    quad_gate_t next;                /* the gate being decided */
    resid_src_t src;                 /* the residual its median is taken of */
    ell_run_t run;                   /* the time-sliced fit's state (magcal_ellipsoid_fit_step) */
} ell_scratch_t;

/* Start the residual pass (phase ELL_PH_RP, in src/fit/ellipsoid.c) of the samples `gate` keeps
 * under `cal`; its results in r->rp (rms, kept, mx), then phase `ret`. */
void magcal_ell_rp_start(ell_run_t *r, const magcal_ellipsoid_cal_t *cal, const quad_gate_t *gate,
                         const ell_ws_t *ws, uint8_t ret);
/* Start the median of |r| (residual `src`) over the `kept` samples `gate` keeps, max |r| =
 * max_abs (with ws->res set, |r| and the verdicts are read from there); result r->med.result,
 * then phase `ret`. */
void magcal_ell_med_start(ell_run_t *r, const resid_src_t *src, const quad_gate_t *gate,
                          const ell_ws_t *ws, size_t kept, float max_abs, uint8_t ret);
/* Explain the failure st of a fit (NO_MOTION / SINGLE_AXIS when the data say so): the next
 * phases return the status. */
void magcal_ell_explain_start(ell_run_t *r, magcal_status_t st);
/* sqrt(smallest / middle eigenvalue) of a packed scatter (xx, yx, yy, zx, zy, zz). */
float magcal_ell_planarity(const float sc[6], struct ell_scratch_s *ws);
/* One phase >= ELL_PH_TRUST_FIRST: the algebraic SNR, the trust gates (order: motion, one axis,
 * residual, observability, field; the diagnostics into sw->dg, then ELL_PH_OUT), the failure
 * explanation, the median and the motion SNR. Returns ELL_CONT, ELL_YIELD or a final status. */
int magcal_ell_trust_phase(struct ell_scratch_s *sw, ell_bud_t *b);

/* magcal_ellipsoid_fit_step inside a larger step: first == 0 when that step has already done
 * work (then no visit is forced: the fit may do nothing and return MAGCAL_IN_PROGRESS). */
magcal_status_t magcal_ell_fit_step_in(magcal_ellipsoid_fit_slice_t *s, uint32_t budget, int first);

/* Sample k kept by the current gate: from ws->keep when stored, else recomputed. */
static inline int magcal_ell_kept(const ell_ws_t *ws, const quad_gate_t *gate,
                                  const magcal_vec3_t *m, size_t k)
{
    if (ws->keep != NULL) {
        return ((ws->keep[k] & 1u) != 0u) ? 1 : 0;
    }
    return magcal_ell_gate_keeps(gate, &m[k]);
}

/* ---- shared by src/fit/ellipsoid.c, ellipsoid_solve.c and ellipsoid_cov.c (the split of the fit) */

#define NQ MAGCAL_ELL_NQ
#define COV_CELLS ((size_t)MAGCAL_ELLIPSOID_COV_AZ * MAGCAL_ELLIPSOID_COV_EL)
#define MIN_QUADRIC_POINTS 10u
#define MIN_SPHERE_POINTS 4u
#define MAX_REFITS_LIMIT 8u
#define INVITER_STEPS 8u
#define INVITER_SHIFT_TRIES 3u

/* Weights of the time-sliced fit: estimated Cortex-M4F instructions of one visit of each phase
 * (docs/calibration_3d.md "Time-sliced fit"): measured per phase on QEMU mps2-an386 (-icount
 * shift=0, tools/bench/m4f_image/main_cont3.c) on a 441-sample tumble at the default budget
 * (a visit inside a chunked pass, loop and budget check included), rounded up. */
#define W_CHECK 400u        /* configuration check */
#define W_N1 110u            /* mean: finiteness + 3 Kahan sums of one sample */
#define W_N2 120u            /* scatter: 6 Kahan sums of one sample */
#define W_NORM_DONE 3300u   /* scale, planarity (3x3 Jacobi) */
#define W_ACC 290u          /* design row + 55 products of one sample, block flush amortised */
#define W_SPHERE 2400u      /* 4x4 sphere solve, coverage centre */
#define W_COV 150u           /* coverage cell of one sample */
#define W_COV_DONE 900u     /* coverage count, model choice */
#define W_SOLVE4 2400u      /* sphere model */
#define W_SOLVE9 7500u      /* 9x9 normal equations, LDL^T */
#define W_SOLVE10 60000u    /* 10-parameter inverse iteration (forced model only; not cut further) */
#define W_EXTRACT 4000u     /* centre, k, Sylvester, 3x3 square root (Jacobi) */
#define W_KEEP 10u           /* one verdict set */
#define W_UNIT 300u         /* loop bookkeeping */
#define W_REGATE 75u        /* stored residual against the new gate */
#define W_REGATE_RECOMP 280u /* both gates' residuals recomputed (no workspace) */
#define W_REGATE_ROW 600u   /* a sample whose verdict changes: design row + 55 Kahan sums */
#define W_SETTLE 15u         /* one verdict settled */
#define W_RP 120u            /* residual pass: one sample (residual stored) */
#define W_RP_RECOMP 220u     /* residual pass: gate and residual recomputed */
#define W_OUT 400u          /* the result written */

/* ellipsoid_solve.c: design rows, the normal equations' accumulation passes, the solvers */
void magcal_ell_acc_start(ell_scratch_t *sw);

/* Pass 3: the normal matrix of every sample (blocked Kahan sums, the block state in the run). */
int magcal_ell_acc_range(ell_scratch_t *sw, ell_bud_t *b);

/*
 * Move the normal matrix `acc` (of the samples the gate keeps) to the samples the next gate
 * keeps: only the samples whose verdict changes are added or removed (a refit after rejecting a
 * few outliers costs one residual pass, not a new accumulation); r->kept_new counts the kept.
 */
int magcal_ell_regate_range(ell_scratch_t *sw, ell_bud_t *b);

/* After regate: the stored verdicts become the next gate's (adopt) or stay the old one's; then
 * the loop ends (the gate did not change) or the model is fitted again. */
int magcal_ell_settle_range(ell_scratch_t *sw, ell_bud_t *b);

/*
 * Quadric coefficients (a, b, c, f, g, h, p, q, r, d) of
 *   a x^2 + b y^2 + c z^2 + 2f yz + 2g xz + 2h xy + 2p x + 2q y + 2r z + d = 0
 * in normalised coordinates -> calibration in raw coordinates (cal is scratch until MAGCAL_OK).
 */
magcal_status_t magcal_ell_extract_quadric(ell_scratch_t *ws, const float mu[3], float s,
                                           float field_cfg, magcal_ellipsoid_sqrt_t method,
                                           magcal_ellipsoid_cal_t *cal);

magcal_status_t magcal_ell_solve_quadric9(const quad_acc_t *acc, float *a, float tau,
                                          float coef[NQ], float *min_pivot);

/* Smallest eigenvector of D^T D by inverse iteration with a shifted LDL^T (algorithms.md 3.2). */
magcal_status_t magcal_ell_solve_quadric10(const quad_acc_t *acc, float *a, float tau,
                                           float coef[NQ], float *min_pivot);

/* Sphere x^2+y^2+z^2 + C x + D y + E z + G0 = 0 from the same moments. */
magcal_status_t magcal_ell_solve_sphere(const quad_acc_t *acc, float *a, const float mu[3],
                                        float s, float field_cfg, float tau,
                                        magcal_ellipsoid_cal_t *cal, float *min_pivot);

/* ellipsoid_cov.c: coverage cells */
/* The coverage cells of samples k0..k1-1 around c into bits (samples within tiny of c skipped). */
void magcal_ell_coverage_cells(const magcal_vec3_t *m, size_t k0, size_t k1, const float c[3],
                               float tiny, uint32_t bits[3]);

float magcal_ell_coverage_count(const uint32_t bits[3]);

/* ---- shared by src/fit/ellipsoid_trust.c and ellipsoid_obs.c (the trust gates) ---- */

#define MED_BINS MAGCAL_ELL_MED_BINS /* histogram bins per pass of the median |residual|: 2 passes reach 0.1 % on a shell */
#define MED_PASSES 4u    /* refinement passes: resolution (max |r|) / 128^4 at worst */
#define PLANAR_MAX 0.15f /* planarity below this: one rotation axis dominates (SINGLE_AXIS) */
#define INFO_MAX_N MAGCAL_ELL_INFO_N /* centre information: 3 offset + 6 symmetric shape parameters */

/* Weights of the trust phases (estimated Cortex-M4F instructions per visit, measured as those of
 * src/fit/ellipsoid.c). */
#define W_T_UNIT 300u       /* bookkeeping, a gate decision */
#define W_T_SOLVE9 7500u    /* 9x9 LDL^T of the algebraic quadric */
#define W_T_ASNR 85u        /* one algebraic residual */
#define W_T_MED_PASS 900u   /* histogram clear + bin search of one median pass */
#define W_T_MED 60u         /* one sample into the histogram (|r| stored) */
#define W_T_MED_RECOMP 190u  /* the same, gate and residual recomputed */
#define W_T_INFO 440u       /* one sample's information row, 31 moment sums x 2 */
#define W_T_INFO_RECOMP 530u
#define W_T_INFO_DONE 1800u  /* flush, moments expanded, direction scatter */
#define W_T_FACTOR 5000u    /* (J^T J)^-1: the 9x9 LDL^T factorisation */
#define W_T_SUBST 1500u     /* one of its 9 substitutions (a column of the inverse) */
#define W_T_SWM 2000u       /* one row k of the sandwich from the summed meat */
#define W_T_SWP 600u        /* one sample of the exact second sandwich pass */
#define W_T_DIAG 5500u      /* two 3x3 Jacobi eigen-decompositions, the gates */

/* ellipsoid_obs.c: observability (information rows, sandwich covariance), the trust phases it runs */
/* One row k of C = inv meat inv from the summed meat (see centre_info below): offset block into
 * cc (lower triangle), shape diagonal into sd[3..np); 0 when the rounding bound is above 1 % of
 * the diagonal term (then the exact second pass decides). */
int magcal_ell_sandwich_row(ell_scratch_t *sw, size_t np, size_t cnt, size_t k);

/* The same sandwich from a second pass over the samples: sum r_i^2 (J_i . inv_k)(J_i . inv_l). */
int magcal_ell_swp_range(ell_scratch_t *sw, ell_bud_t *b);

/* One pass: J^T J (blocked Kahan, in acc) and the sandwich's meat (plain sums: a 1-significant-digit
 * gate), so the covariance needs no second pass over the samples. */
int magcal_ell_info_range(ell_scratch_t *sw, ell_bud_t *b);

/* The pass's last block, the meat's moments into its packed terms, the scatter of the directions
 * about their mean (from the n n^T block); then the inverse (or the diagnostics: too few). */
int magcal_ell_ph_info_done(ell_scratch_t *sw, ell_bud_t *b);

/* The factorisation of J^T J (into sw->mat) for its inverse; 0 when singular. */
int magcal_ell_info_factor(ell_scratch_t *sw, size_t np);

/* The observability diagnostics from centre_info's matrices (relative to F). */
void magcal_ell_centre_diag(const ell_ws_t *ws, int stage, int sphere, float f, trust_diag_t *res);

#endif /* MAGCAL_ELLIPSOID_INTERNAL_H */
