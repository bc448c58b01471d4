/*
 * libFuzzer harness for the 3-D calibration: the INS/GNSS-aided estimator (every epoch through
 * magcal_aided_update, both objectives, forgetting, noise compensation, fuzzed configuration and
 * prior), the 3-D OPTICS density stage (magcal_optics_filter3, automatic parameters, both
 * orderings) and the ellipsoid fit with its per-sample outlier mask, on the same samples.
 *
 * Input layout (little endian; missing bytes read as 0):
 *   u8 flags: bit 0 objective (0 combined, 1 vector), bit 1 lambda 0.995, bit 2 noise_rel 1e-3,
 *             bit 3 prior G0/V0 from the input (raw f32 bits), bits 4-5 ellipsoid model enum (raw),
 *             bit 6 raw epochs (else synthetic), bit 7 sigma_rel/sigma_f_rel from the input (raw)
 *   [bit 7] f32 sigma_rel, f32 sigma_f_rel        [bit 3] 9 x f32 G0 (row-major), 3 x f32 V0
 *   raw epochs (bit 6): per epoch 10 x f32: m x/y/z, roll, pitch, yaw (rad), B_ref N/E/D, dop
 *   synthetic (else): header 9 x i8 W - I (x 0.15/128), 3 x i8 V (x 0.5 uT), then per epoch
 *     u8 yaw step (x 0.1 deg, cumulative), i8 pitch, i8 roll (x 0.05 deg), 3 x i8 noise
 *     (x 0.005 uT), u8 dop (/ 40); field m = W C_n^b B + V + noise, B = (20, 1.2, 44) uT.
 *
 * Invariants: documented statuses only; a rejected configuration leaves the instance unusable
 * (NOT_INITIALISED); counters add up (seen = accepted + gated, n_total_field <= accepted); a
 * written estimate is finite with F > 0 and non-negative finite diagnostics; the vector-only
 * estimator never reports total-field epochs; the ellipsoid fit's outlier mask counts exactly
 * n_rejected on its own input and an OK fit is finite; the density stage returns a documented
 * status, leaves the mask untouched on failure, and CLASSIC and IMPROVED keep the same samples.
 */
#include <math.h>

#include "fuzz_common.h"
#include "magcal/aided.h"
#include "magcal/ellipsoid.h"
#include "magcal/optics.h"

/* magcal_ellipsoid_fit's fixed scratch (the workspace-free fit: no per-sample storage) */
static magcal_ellipsoid_fit_scratch_t g_fit_scratch;

#define FZ_MAX_EPOCHS 4096u

static magcal_aided_t fz_inst;
static magcal_vec3_t fz_m[FZ_MAX_EPOCHS];
static uint8_t fz_mask[FZ_MAX_EPOCHS];
static uint8_t fz_mask2[FZ_MAX_EPOCHS];
static uint32_t fz_work3[(MAGCAL_OPTICS3_FILTER_WORKSPACE_LEN(MAGCAL_MAX_SAMPLES) + 3u) / 4u];

/* 3-D OPTICS density stage, both orderings, automatic parameters, on the first FZ_DENSITY_N
 * samples at most (its automatic rule is O(n^2): 1024 samples under ASan would cut the harness to
 * ~15 executions/s). */
#define FZ_DENSITY_N 300u
static void fz_density(size_t n)
{
    magcal_optics_cfg_t cfg = MAGCAL_OPTICS_CFG_DEFAULT;
    magcal_optics_result_t info;
    magcal_status_t st;
    magcal_status_t st2;
    size_t i;
    if (n > FZ_DENSITY_N) {
        n = FZ_DENSITY_N;
    }
    (void)memset(fz_mask, 0xA5, sizeof fz_mask);
    st = magcal_optics_filter3(&cfg, fz_m, n, fz_work3, sizeof fz_work3, fz_mask, &info);
    FUZZ_CHECK(st == MAGCAL_OK || st == MAGCAL_ERR_TOO_FEW_POINTS || st == MAGCAL_ERR_DEGENERATE ||
                   st == MAGCAL_ERR_ALL_NOISE || st == MAGCAL_ERR_ARG,
               "filter3 status");
    cfg.order = MAGCAL_OPTICS_CLASSIC;
    (void)memset(fz_mask2, 0xA5, sizeof fz_mask2);
    st2 = magcal_optics_filter3(&cfg, fz_m, n, fz_work3, sizeof fz_work3, fz_mask2, NULL);
    FUZZ_CHECK(st2 == st, "filter3 classic status == improved status");
    for (i = 0u; i < n; ++i) {
        if (st != MAGCAL_OK) {
            FUZZ_CHECK(fz_mask[i] == 0xA5u && fz_mask2[i] == 0xA5u, "filter3 mask untouched on failure");
        } else {
            FUZZ_CHECK(fz_mask[i] <= 1u && fz_mask[i] == fz_mask2[i], "filter3 mask 0/1, classic == improved");
        }
    }
}

static int fz_finite3(const magcal_vec3_t *v)
{
    return isfinite(v->x) && isfinite(v->y) && isfinite(v->z);
}

static void fz_check_cal(const magcal_ellipsoid_cal_t *cal, const char *what)
{
    int i;
    int j;
    FUZZ_CHECK(fz_finite3(&cal->v), what);
    for (i = 0; i < 3; ++i) {
        for (j = 0; j < 3; ++j) {
            FUZZ_CHECK(isfinite(cal->g[i][j]), what);
        }
    }
}

/* Synthetic epoch from the byte stream (see the layout above). */
static void fz_synthetic(fuzz_in_t *in, const double w[3][3], const double v[3], double *yaw,
                         magcal_aided_epoch_t *ep)
{
    static const double b[3] = {20.0, 1.2, 44.0};
    const double d2r = 3.14159265358979323846 / 180.0;
    double pitch;
    double roll;
    double c[3][3];
    double h[3];
    float cf[3][3];
    int i;
    *yaw += 0.1 * d2r * (double)fuzz_u8(in);
    pitch = 0.05 * d2r * (double)(int8_t)fuzz_u8(in);
    roll = 0.05 * d2r * (double)(int8_t)fuzz_u8(in);
    (void)magcal_aided_dcm((float)roll, (float)pitch, (float)*yaw, cf);
    for (i = 0; i < 3; ++i) {
        c[i][0] = cf[i][0];
        c[i][1] = cf[i][1];
        c[i][2] = cf[i][2];
    }
    for (i = 0; i < 3; ++i) {
        h[i] = c[0][i] * b[0] + c[1][i] * b[1] + c[2][i] * b[2];
    }
    ep->m.x = (float)(w[0][0] * h[0] + w[0][1] * h[1] + w[0][2] * h[2] + v[0] + 0.005 * (int8_t)fuzz_u8(in));
    ep->m.y = (float)(w[1][0] * h[0] + w[1][1] * h[1] + w[1][2] * h[2] + v[1] + 0.005 * (int8_t)fuzz_u8(in));
    ep->m.z = (float)(w[2][0] * h[0] + w[2][1] * h[1] + w[2][2] * h[2] + v[2] + 0.005 * (int8_t)fuzz_u8(in));
    ep->roll_rad = (float)roll;
    ep->pitch_rad = (float)pitch;
    ep->yaw_rad = (float)*yaw;
    ep->b_ref_ned.x = (float)b[0];
    ep->b_ref_ned.y = (float)b[1];
    ep->b_ref_ned.z = (float)b[2];
    ep->dop = (float)fuzz_u8(in) / 40.0f;
}

static void fz_raw(fuzz_in_t *in, magcal_aided_epoch_t *ep)
{
    ep->m.x = fuzz_f32(in);
    ep->m.y = fuzz_f32(in);
    ep->m.z = fuzz_f32(in);
    ep->roll_rad = fuzz_f32(in);
    ep->pitch_rad = fuzz_f32(in);
    ep->yaw_rad = fuzz_f32(in);
    ep->b_ref_ned.x = fuzz_f32(in);
    ep->b_ref_ned.y = fuzz_f32(in);
    ep->b_ref_ned.z = fuzz_f32(in);
    ep->dop = fuzz_f32(in);
}

static void fz_ellipsoid(size_t n, uint8_t flags)
{
    magcal_ellipsoid_cfg_t cfg = MAGCAL_ELLIPSOID_CFG_DEFAULT;
    magcal_ellipsoid_result_t res;
    magcal_status_t st;
    size_t nout = 0u;
    cfg.model = (magcal_ellipsoid_model_t)((flags >> 4) & 3u);
    st = magcal_ellipsoid_fit(fz_m, n, &cfg, &g_fit_scratch, &res);
    FUZZ_CHECK(st == MAGCAL_OK || st == MAGCAL_ERR_TOO_FEW_POINTS || st == MAGCAL_ERR_NONFINITE ||
                   st == MAGCAL_ERR_COVERAGE || st == MAGCAL_ERR_DEGENERATE ||
                   st == MAGCAL_ERR_ILL_CONDITIONED || st == MAGCAL_ERR_NOT_ELLIPSOID ||
                   st == MAGCAL_ERR_NOT_CONVERGED || st == MAGCAL_ERR_TOO_MANY_OUTLIERS ||
                   st == MAGCAL_ERR_ARG || st == MAGCAL_ERR_NO_MOTION || st == MAGCAL_ERR_SINGLE_AXIS ||
                   st == MAGCAL_ERR_RESIDUAL || st == MAGCAL_ERR_FIELD_MAGNITUDE,
               "ellipsoid_fit status");
    if (st != MAGCAL_OK) {
        return;
    }
    /* an OK passed every trust gate (issue 12) */
    FUZZ_CHECK(res.motion_snr >= cfg.min_motion_snr && res.centre_std_rel <= cfg.max_centre_std_rel &&
                   res.shape_std <= cfg.max_shape_std,
               "ellipsoid trust gates");
    fz_check_cal(&res.cal, "ellipsoid cal finite");
    FUZZ_CHECK(isfinite(res.cal.field) && res.cal.field > 0.0f, "ellipsoid field");
    FUZZ_CHECK(res.n_used + res.n_rejected == n, "ellipsoid counts");
    st = magcal_ellipsoid_outliers(&res, fz_m, n, fz_mask, &nout);
    FUZZ_CHECK(st == MAGCAL_OK, "outliers on the fit's own input");
    FUZZ_CHECK(nout == res.n_rejected, "outlier mask count == n_rejected");
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    fuzz_in_t in = {data, size, 0u};
    magcal_aided_cfg_t cfg = MAGCAL_AIDED_CFG_DEFAULT;
    magcal_aided_result_t res;
    magcal_status_t st;
    double w[3][3];
    double v[3];
    double yaw = 0.0;
    uint8_t flags = fuzz_u8(&in);
    uint32_t seen = 0u;
    uint32_t accepted = 0u;
    size_t n = 0u;
    int i;
    int j;

    cfg.objective = ((flags & 1u) != 0u) ? MAGCAL_AIDED_OBJ_VECTOR : MAGCAL_AIDED_OBJ_COMBINED;
    cfg.lambda = ((flags & 2u) != 0u) ? 0.995f : 1.0f;
    cfg.noise_rel = ((flags & 4u) != 0u) ? 1e-3f : 0.0f;
    if ((flags & 0x80u) != 0u) {
        cfg.sigma_rel = fuzz_f32(&in);
        cfg.sigma_f_rel = fuzz_f32(&in);
    }
    if ((flags & 8u) != 0u) {
        for (i = 0; i < 3; ++i) {
            for (j = 0; j < 3; ++j) {
                cfg.prior.g[i][j] = fuzz_f32(&in);
            }
        }
        cfg.prior.v.x = fuzz_f32(&in);
        cfg.prior.v.y = fuzz_f32(&in);
        cfg.prior.v.z = fuzz_f32(&in);
    }
    (void)memset(&fz_inst, 0, sizeof fz_inst);
    st = magcal_aided_init(&fz_inst, &cfg);
    FUZZ_CHECK(st == MAGCAL_OK || st == MAGCAL_ERR_ARG || st == MAGCAL_ERR_NONFINITE, "init status");
    if (st != MAGCAL_OK) {
        FUZZ_CHECK(magcal_aided_get(&fz_inst, &res) == MAGCAL_ERR_NOT_INITIALISED, "rejected cfg: unusable");
        return 0;
    }
    for (i = 0; i < 3; ++i) {
        for (j = 0; j < 3; ++j) {
            w[i][j] = ((i == j) ? 1.0 : 0.0) + 0.15 / 128.0 * (double)(int8_t)fuzz_u8(&in);
        }
    }
    for (i = 0; i < 3; ++i) {
        v[i] = 0.5 * (double)(int8_t)fuzz_u8(&in);
    }
    while (fuzz_left(&in) > 0u && n < FZ_MAX_EPOCHS) {
        magcal_aided_epoch_t ep;
        magcal_aided_gate_t why = MAGCAL_AIDED_GATE_COUNT;
        if ((flags & 0x40u) != 0u) {
            fz_raw(&in, &ep);
        } else {
            fz_synthetic(&in, w, v, &yaw, &ep);
        }
        st = magcal_aided_update(&fz_inst, &ep, &why);
        FUZZ_CHECK(st == MAGCAL_OK || st == MAGCAL_ERR_GATED || st == MAGCAL_ERR_NONFINITE ||
                       st == MAGCAL_ERR_ARG || st == MAGCAL_ERR_ZERO_FIELD,
                   "update status");
        if (st == MAGCAL_OK) {
            FUZZ_CHECK(why == MAGCAL_AIDED_GATE_NONE, "accepted: no gate");
            seen++;
            accepted++;
        } else if (st == MAGCAL_ERR_GATED) {
            FUZZ_CHECK(why > MAGCAL_AIDED_GATE_NONE && why < MAGCAL_AIDED_GATE_COUNT, "gate reason");
            seen++;
        }
        if (fz_finite3(&ep.m)) {
            fz_m[n] = ep.m;
            n++;
        }
    }
    st = magcal_aided_get(&fz_inst, &res);
    FUZZ_CHECK(st == MAGCAL_OK || st == MAGCAL_ERR_UNOBSERVABLE || st == MAGCAL_ERR_NOT_CONVERGED ||
                   st == MAGCAL_ERR_TOO_FEW_POINTS,
               "get status");
    if (st != MAGCAL_ERR_TOO_FEW_POINTS) {
        uint32_t g = 0u;
        /* an OK epoch is used (n_accepted) or held back as stationary (n_still), aided.h */
        FUZZ_CHECK(res.n_seen == seen && res.n_accepted + res.n_still == accepted, "seen/accepted counters");
        for (i = 1; i < (int)MAGCAL_AIDED_GATE_COUNT; ++i) {
            g += res.gated[i];
        }
        FUZZ_CHECK(g + res.n_accepted + res.n_still == res.n_seen, "gated + accepted + still == seen");
        FUZZ_CHECK(res.n_total_field <= res.n_accepted, "total-field epochs <= accepted");
        FUZZ_CHECK(cfg.objective == MAGCAL_AIDED_OBJ_COMBINED || res.n_total_field == 0u,
                   "vector objective: no total-field epochs");
        fz_check_cal(&res.cal, "aided cal finite");
        FUZZ_CHECK(isfinite(res.cal.field) && res.cal.field > 0.0f, "aided field");
        FUZZ_CHECK(isfinite(res.resid_rms) && res.resid_rms >= 0.0f, "resid_rms");
        FUZZ_CHECK(isfinite(res.resid_f_rms) && res.resid_f_rms >= 0.0f, "resid_f_rms");
        FUZZ_CHECK(res.n_prior_dirs <= 4u, "prior directions");
        FUZZ_CHECK((st == MAGCAL_ERR_UNOBSERVABLE) == (res.n_prior_dirs > 0u), "unobservable iff prior used");
    }
    fz_density(n);
    fz_ellipsoid(n, flags);
    return 0;
}
