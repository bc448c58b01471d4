/*
 * libFuzzer harness for the calibration pipeline end to end: init (with fuzzed overrides), push
 * a fuzzed sample stream (NaN, +/-Inf, subnormals, huge values included), run against a previous
 * calibration, then classify, flags and heading on every stored sample.
 *
 * Input layout (little endian; missing bytes read as 0):
 *   u8  mode      bits 0-1 filter, bit 2 use_consensus, bits 3-4 form (all four),
 *                 bits 5-6 previous calibration (0 identity, 1 usable, 2 blank flash, 3 radius 0),
 *                 bit 7 sample format (0: raw float32 pairs, 1: int16 pairs times `scale`)
 *   u16 capacity  16 + value mod (MAGCAL_MAX_SAMPLES - 15)
 *   u8  gates     bits 0-3 max_per_bin, bits 4-7 min_spacing_deg / 2
 *   u8  override  bit 0: eps and min_pts below are applied (else automatic)
 *   f32 eps       raw bits (NaN, negative, Inf are legal fuzz values)
 *   u8  min_pts
 *   f32 scale     raw bits (format 1 only)
 *   then samples: 8 bytes (f32 x, f32 y) or 4 bytes (i16 x, i16 y) each, until the input ends.
 *
 * Invariants: every status is a documented one for its call; push stores exactly the finite
 * samples that fit (NONFINITE for NaN/Inf, BUFFER_FULL at capacity); a failed run() leaves the
 * caller's calibration bit-identical and the report's status equal to the return value; an OK
 * run() adopted a calibration that magcal_cal2d_validate() accepts, and every heading computed
 * with it is finite and in [0, 360).
 */
#include <math.h>

#include "fuzz_common.h"
#include "magcal/calibrator.h"
#include "magcal/heading.h"

#define FZ_CAP_MAX MAGCAL_MAX_SAMPLES

static magcal_vec2_t fz_buf[FZ_CAP_MAX];
static magcal_vec2_t fz_kept[FZ_CAP_MAX];
static uint32_t fz_work[(MAGCAL_CALIBRATOR_WORKSPACE_LEN(FZ_CAP_MAX) + 3u) / 4u];

static int fz_run_status_ok(magcal_status_t st)
{
    switch (st) {
    case MAGCAL_OK:
    case MAGCAL_ERR_TOO_FEW_POINTS:
    case MAGCAL_ERR_DEGENERATE:
    case MAGCAL_ERR_ALL_NOISE:
    case MAGCAL_ERR_COVERAGE:
    case MAGCAL_ERR_TOO_MANY_OUTLIERS:
    case MAGCAL_ERR_HYPERBOLA:
    case MAGCAL_ERR_PARABOLA:
    case MAGCAL_ERR_IMAGINARY:
    case MAGCAL_ERR_ILL_CONDITIONED:
    case MAGCAL_ERR_RADIUS_RANGE:
    case MAGCAL_ERR_AXIS_RATIO:
    case MAGCAL_ERR_RESIDUAL:
    case MAGCAL_ERR_NOT_BETTER:
    case MAGCAL_ERR_ARG:
    case MAGCAL_ERR_WORKSPACE:
        return 1;
    default:
        return 0;
    }
}

static magcal_cal2d_t fz_previous(unsigned which)
{
    magcal_cal2d_t c = MAGCAL_CAL2D_IDENTITY;
    if (which == 1u || which == 3u) { /* a plausible stored calibration */
        c.offset.x = 12.5f;
        c.offset.y = -7.25f;
        c.m[0][0] = 1.1f;
        c.m[0][1] = 0.05f;
        c.m[1][0] = 0.05f;
        c.m[1][1] = 0.9f;
        c.radius = which == 1u ? 40.0f : 0.0f;
    } else if (which == 2u) { /* blank flash */
        (void)memset(&c, 0xFF, sizeof c);
    }
    return c;
}

static void fz_check_headings(const magcal_cal2d_t *cur, size_t n, int must_work)
{
    size_t i;
    for (i = 0u; i < n; ++i) {
        float mag = -1.0f;
        float tru = -1.0f;
        magcal_status_t st = magcal_heading_compute(cur, fz_kept[i], 3.5f, &mag, &tru);
        FUZZ_CHECK(fuzz_status_known(st), "heading: unknown status");
        if (must_work) {
            FUZZ_CHECK(st == MAGCAL_OK || st == MAGCAL_ERR_ZERO_FIELD || st == MAGCAL_ERR_NONFINITE,
                       "heading with an adopted calibration: unexpected status");
        }
        if (st == MAGCAL_OK) {
            FUZZ_CHECK(isfinite(mag) && mag >= 0.0f && mag < 360.0f, "magnetic heading range");
            FUZZ_CHECK(isfinite(tru) && tru >= 0.0f && tru < 360.0f, "true heading range");
        } else {
            FUZZ_CHECK(mag == -1.0f && tru == -1.0f, "heading output written on failure");
        }
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    fuzz_in_t in = {data, size, 0u};
    magcal_calibrator_t cal;
    magcal_calibrator_cfg_t cfg = MAGCAL_CALIBRATOR_CFG_DEFAULT;
    magcal_cal2d_t cur;
    magcal_cal2d_t before;
    magcal_cal_report_t rep;
    magcal_status_t st;
    uint8_t mode = fuzz_u8(&in);
    size_t cap = 16u + (size_t)fuzz_u16(&in) % (FZ_CAP_MAX - 15u);
    uint8_t gates = fuzz_u8(&in);
    uint8_t ovr = fuzz_u8(&in);
    float eps = fuzz_f32(&in);
    uint8_t min_pts = fuzz_u8(&in);
    float scale = fuzz_f32(&in);
    int as_int16 = (mode & 0x80u) != 0u;
    size_t n_kept = 0u;
    size_t i;

    cfg.filter = (magcal_calibrator_filter_t)(mode & 3u);
    cfg.use_consensus = (uint8_t)((mode >> 2) & 1u);
    cfg.form = (magcal_corr_form_t)(((unsigned)mode >> 3) % 4u); /* every form, KPHI included */
    cfg.max_per_bin = (uint16_t)(gates & 0x0Fu);
    cfg.min_spacing_deg = 2.0f * (float)(gates >> 4);
    if ((ovr & 1u) != 0u) {
        cfg.eps = eps;
        cfg.min_pts = min_pts;
    }
    st = magcal_calibrator_init(&cal, &cfg, fz_buf, cap, fz_work, sizeof fz_work);
    if ((ovr & 1u) != 0u) {
        magcal_status_t want = MAGCAL_OK;
        if (!isfinite(eps)) {
            want = MAGCAL_ERR_NONFINITE;
        } else if (eps < 0.0f || min_pts == 1u || min_pts > MAGCAL_MAX_MIN_PTS) {
            want = MAGCAL_ERR_ARG;
        }
        FUZZ_CHECK(st == want, "init: status for the eps/min_pts override");
        if (st != MAGCAL_OK) {
            cfg.eps = 0.0f;
            cfg.min_pts = 0u;
            st = magcal_calibrator_init(&cal, &cfg, fz_buf, cap, fz_work, sizeof fz_work);
        }
    }
    FUZZ_CHECK(st == MAGCAL_OK, "init with valid settings");

    /* push the stream */
    while (fuzz_left(&in) >= (as_int16 ? 4u : 8u)) {
        magcal_vec2_t p;
        size_t n0 = magcal_calibrator_count(&cal);
        if (as_int16) {
            int16_t xi = (int16_t)fuzz_u16(&in);
            int16_t yi = (int16_t)fuzz_u16(&in);
            p.x = (float)xi * scale;
            p.y = (float)yi * scale;
        } else {
            p.x = fuzz_f32(&in);
            p.y = fuzz_f32(&in);
        }
        st = magcal_calibrator_push(&cal, p);
        if (!isfinite(p.x) || !isfinite(p.y)) {
            FUZZ_CHECK(st == MAGCAL_ERR_NONFINITE, "push: non-finite sample not rejected");
        } else if (n0 == cap) {
            FUZZ_CHECK(st == MAGCAL_ERR_BUFFER_FULL, "push: full buffer not reported");
        } else {
            FUZZ_CHECK(st == MAGCAL_OK || st == MAGCAL_ERR_GATED, "push: status");
            if (cfg.max_per_bin == 0u && cfg.min_spacing_deg == 0.0f) {
                FUZZ_CHECK(st == MAGCAL_OK, "push: gated with the gate off");
            }
        }
        if (st == MAGCAL_OK) {
            FUZZ_CHECK(magcal_calibrator_count(&cal) == n0 + 1u, "push: count after OK");
            fz_kept[n_kept++] = p;
        } else {
            FUZZ_CHECK(magcal_calibrator_count(&cal) == n0, "push: count after a refusal");
        }
        {
            float cov = magcal_calibrator_coverage_deg(&cal);
            FUZZ_CHECK(cov >= 0.0f && cov <= 360.0f, "live coverage range");
        }
    }

    /* run against a previous calibration */
    cur = fz_previous(((unsigned)mode >> 5) & 3u);
    before = cur;
    st = magcal_calibrator_run(&cal, &cur, &rep);
    if (!fz_run_status_ok(st)) {
        fprintf(stderr, "run() returned %d (%s)\n", (int)st, magcal_status_str(st));
    }
    FUZZ_CHECK(fz_run_status_ok(st), "run: undocumented status");
    FUZZ_CHECK(rep.status == st, "report status differs from the return value");
    FUZZ_CHECK(rep.samples == (uint16_t)n_kept, "report samples");
    if (st != MAGCAL_OK) {
        FUZZ_CHECK(memcmp(&cur, &before, sizeof cur) == 0, "failed run changed the calibration");
        FUZZ_CHECK(rep.adopted == 0u, "failed run reports adoption");
        FUZZ_CHECK(magcal_calibrator_state(&cal) == MAGCAL_CALIBRATOR_FAILED, "state after failure");
    } else {
        FUZZ_CHECK(rep.adopted == 1u, "OK without adoption");
        FUZZ_CHECK(magcal_cal2d_validate(&cur) == MAGCAL_OK, "adopted calibration invalid");
        FUZZ_CHECK(memcmp(&cur, &rep.cal, sizeof cur) == 0, "adopted calibration differs from report");
        FUZZ_CHECK(isfinite(rep.radius) && rep.radius > 0.0f, "adopted radius");
        FUZZ_CHECK(isfinite(rep.est_heading_err_deg) && rep.est_heading_err_deg >= 0.0f,
                   "estimated heading error");
        FUZZ_CHECK(rep.coverage_deg >= cfg.min_coverage_deg && rep.coverage_deg <= 360.0f,
                   "coverage of an adopted calibration");
        FUZZ_CHECK(rep.used >= cfg.min_samples && rep.used <= rep.samples, "used count");
        FUZZ_CHECK(magcal_calibrator_state(&cal) == MAGCAL_CALIBRATOR_CALIBRATED, "state after OK");
    }

    /* per-sample queries */
    for (i = 0u; i < n_kept; ++i) {
        int v = -1;
        uint8_t fl = 0u;
        magcal_status_t s1 = magcal_calibrator_classify(&cal, fz_kept[i], &v);
        magcal_status_t s2 = magcal_calibrator_inlier(&cal, i, &v);
        magcal_status_t s3 = magcal_calibrator_flags(&cal, i, &fl);
        FUZZ_CHECK(s1 == MAGCAL_OK || s1 == MAGCAL_ERR_STATE, "classify status");
        FUZZ_CHECK(s2 == MAGCAL_OK || s2 == MAGCAL_ERR_STATE || s2 == MAGCAL_ERR_ARG, "inlier status");
        FUZZ_CHECK(s3 == MAGCAL_OK || s3 == MAGCAL_ERR_STATE || s3 == MAGCAL_ERR_ARG, "flags status");
        if (st == MAGCAL_OK) {
            FUZZ_CHECK(s1 == MAGCAL_OK && s2 == MAGCAL_OK && s3 == MAGCAL_OK, "queries after OK");
        }
    }
    fz_check_headings(&cur, n_kept, st == MAGCAL_OK);
    return 0;
}
