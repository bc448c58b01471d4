/*
 * Continuous calibrator, slopes without gravity (continuous.h "Slopes without gravity"). A
 * calibrator that was never given gravity (magcal_cont_push alone) cannot level a sample, and a
 * slope moves its heading: the vertical field Z leaks into the horizontal plane by Z sin(tilt),
 * up to k / R * tilt radians (k / R = Z / H = tan(inclination), 2 at 64 deg). Raw z sees the same
 * slope: a pitch p at magnetic heading psi moves it by about -R sin p cos psi, a roll r by about
 * R sin r sin psi, while the heading moves by about (k / R)(sin p sin psi + sin r cos psi): the
 * spread of raw z about its level value, over the headings driven, measures the slopes, and
 * times k / R the heading error they cause (raw z alone cannot tell the slope at one heading: at
 * east or west a pitch moves the heading most and raw z least, so the measure is a statistic of
 * the roads, not of the sample).
 * The level value is the store's: raw z / raw radius against the corrected heading's cos and sin
 * (the soft iron's leak of x, y into z), a least-squares fit over the store's ring samples in the
 * field-model fit's z pass (cont_fzfit.c), refitted in its sigma pass on the samples within
 * CONT_SL_GATE of the first (4 % of a store 0.47 R off, both sides of a hard-iron step in z, moved
 * the first fit's level by 0.018). The store's spread: the median |residual| about the refit in a
 * pass of its own (a histogram of MAGCAL_CONT_SL_BINS bins up to CONT_SL_GATE; / 0.6745, a
 * normal's RMS), less the sensor's noise (measured on successive samples: the store's are single
 * readings). Online, every clean judged sample's residual smoothed over CONT_SL_SMOOTH_MS (the
 * slope of now, where raw z shows it, from every judged sample but a glitch: an unlevelled hill
 * is a radius mismatch; its square peak-held over CONT_SL_RP_MS), its clipped absolute value's
 * mean over CONT_SL_MS_MS (x 1.25, a normal's RMS: the slopes of now), and the largest mean
 * square seen, decaying over CONT_SL_PK_MS (the slopes of the roads). magcal_cont_heading takes
 * the largest of the four, times k / R and CONT_SL_PEAK, as the heading error the slopes can cause (TILTED above
 * cfg.tilt_trust_deg); they are unknown for CONT_SL_WARM_MS after the first fit, and for
 * CONT_SL_MS_MS (the online mean's time constant) when the store itself shows slopes.
 */
#include "../intake/intake_internal.h"
#include "cont_judge_internal.h"

#define CONT_SL_SMOOTH_MS 1000u /* a residual's smoothing (noise 0.1 uT of 21 falls by ~10 x) */
#define CONT_SL_MS_MS 120000u   /* the online mean's time constant (a few hills, many headings) */
#define CONT_SL_GATE 0.05f      /* a residual enters clipped to this (2.9 deg of pitch), the refit takes those within */
#define CONT_SL_RMS 1.25f       /* a normal's RMS over its mean absolute value (the online mean) */
#define CONT_SL_PEAK 2.0f       /* the heading error the trust compares: this x the RMS */
#define CONT_SL_PK_MS 1800000u  /* the roads' slopes are forgotten over 30 min */
#define CONT_SL_RP_MS 60000u    /* the slope seen last is forgotten over 1 min (a 10 x slope: in 4.6 min) */
#define CONT_SL_TICK_MS 250u    /* the online mean, the peaks and the clocks move this often */
#define CONT_SL_WARM_MS 2000u   /* the slopes are unknown until the online measure has learnt this long */
#define CONT_SL_FLAT 0.5f       /* ... or CONT_SL_MS_MS when the store's slopes exceed this x cfg.tilt_trust_deg */
#define CONT_SL_NOISE_MS 30000u /* time constant of raw z's noise estimate */
#define CONT_SL_PAIR_MS 200u    /* successive samples further apart than this are no pair */
#define CONT_SL_JUMP 0.05f      /* ... and those whose z differs by more than this x |m| (L1) */

/* A fit pass's sample: cos and sin of the corrected heading h (heading.c: atan2(-x, y)) and
 * u = raw z / raw radius; 0 when h is 0 or u not finite. */
static int cont_sl_in(const magcal_cont_t *cc, const magcal_vec2_t *h, float z, float *q)
{
    const float nh = sqrtf(h->x * h->x + h->y * h->y);
    q[0] = z / cc->cal_raw_radius;
    if (!(nh > 0.0f) || !magcal_isfinite_f(q[0])) {
        return 0;
    }
    q[1] = h->y / nh;
    q[2] = -h->x / nh;
    return 1;
}

void magcal_cont_slope_add(magcal_cont_t *cc, const magcal_vec2_t *h, float z)
{
    float q[3];
    if (cont_sl_in(cc, h, z, q) != 0) {
        magcal_lv_sums(cc->sl_acc, q[0], q[1], q[2]);
    }
}

/* The level from the sums q (magcal_lv_solve, intake_internal.h), into cc->sl_a; 1 when solved
 * (the determinant of a store that covers the ring is about n^3 / 4; one heading gives 0). */
static int cont_sl_solve(magcal_cont_t *cc, const float *q)
{
    return magcal_lv_solve(q, 3.0f, 0.01f, cc->sl_a);
}

void magcal_cont_slope_solve(magcal_cont_t *cc)
{
    uint32_t k;
    cc->sl_ok = (uint8_t)(cont_sl_solve(cc, cc->sl_acc) != 0 ? CONT_SL_SOLVED : CONT_SL_NONE);
    for (k = 0u; k < CONT_SL_ACC; ++k) {
        cc->sl_acc[k] = 0.0f; /* the sigma pass's sums next */
    }
    for (k = 0u; k < MAGCAL_CONT_SL_BINS; ++k) {
        cc->sl_h[k] = 0u;
    }
}

/* The residual of raw z / raw radius u at heading (c, s) about the level value. */
static float cont_sl_res(const magcal_cont_t *cc, float u, float c, float s)
{
    return u - (cc->sl_a[0] + cc->sl_a[1] * c + cc->sl_a[2] * s);
}

void magcal_cont_slope_res(magcal_cont_t *cc, const magcal_vec2_t *h, float z)
{
    float q[3];
    if (cc->sl_ok == CONT_SL_SOLVED && cont_sl_in(cc, h, z, q) != 0 &&
        fabsf(cont_sl_res(cc, q[0], q[1], q[2])) <= CONT_SL_GATE) {
        magcal_lv_sums(cc->sl_acc, q[0], q[1], q[2]); /* the refit's */
    }
}

int magcal_cont_slope_refit(magcal_cont_t *cc)
{
    uint32_t k;
    if (cc->sl_ok != CONT_SL_SOLVED) {
        return 0;
    }
    /* the level refitted on the samples within the gate of the first fit: a store that mixes both
     * sides of a hard-iron step in z (4 % of its samples 0.47 R off, on 30-min seed 14) moved the
     * least-squares level by 0.018, which read a flat drive as 2-deg slopes */
    (void)cont_sl_solve(cc, cc->sl_acc);
    cc->sl_acc[9] = 0.0f;
    for (k = 0u; k < MAGCAL_CONT_SL_BINS; ++k) {
        cc->sl_h[k] = 0u;
    }
    return 1;
}

void magcal_cont_slope_hist(magcal_cont_t *cc, const magcal_vec2_t *h, float z)
{
    float q[3];
    if (cont_sl_in(cc, h, z, q) == 0) {
        return;
    }
    {
        const float nb = (float)MAGCAL_CONT_SL_BINS;
        const float b = fabsf(cont_sl_res(cc, q[0], q[1], q[2])) * (nb / CONT_SL_GATE);
        const uint32_t k = (b < nb - 1.0f) ? (uint32_t)b : (MAGCAL_CONT_SL_BINS - 1u);
        cc->sl_h[k]++;
    }
    cc->sl_acc[9] += 1.0f;
}

/* The median of the histogram's |residual| (linear within its bin), NaN when empty. */
static float cont_sl_median(const magcal_cont_t *cc)
{
    const float half = 0.5f * cc->sl_acc[9];
    float below = 0.0f;
    uint32_t k;
    for (k = 0u; k < MAGCAL_CONT_SL_BINS; ++k) {
        const float nk = (float)cc->sl_h[k];
        if (nk > 0.0f && below + nk >= half) {
            return ((float)k + (half - below) / nk) * (CONT_SL_GATE / (float)MAGCAL_CONT_SL_BINS);
        }
        below += nk;
    }
    return NAN;
}

void magcal_cont_slope_end(magcal_cont_t *cc)
{
    const float med = cont_sl_median(cc);
    if (cc->sl_ok == CONT_SL_SOLVED && cc->sl_acc[9] >= 3.0f && magcal_isfinite_f(med)) {
        /* the robust spread about the refitted level (the median of |residual| is 0.6745 of a
         * normal's RMS; a transient's or a step's samples count once each), less the sensor's
         * noise (the store's samples are single readings) */
        const float e = med / 0.6745f;
        cc->sl_vs = fmaxf(e * e - cc->sl_nz / (cc->cal_raw_radius * cc->cal_raw_radius), 0.0f);
        cc->sl_ok = CONT_SL_DONE;
        cc->sl_pk = fmaxf(cc->sl_pk, cc->sl_vs);
    } else {
        cc->sl_ok = CONT_SL_NONE;
    }
    cc->sl_r = 0.0f;
    cc->sl_v = cc->sl_ok == CONT_SL_DONE ? sqrtf(cc->sl_vs) / CONT_SL_RMS : 0.0f;
}

void magcal_cont_slope_noise(magcal_cont_t *cc, const magcal_vec3_t *m, uint32_t t_ms)
{
    float d;
    if (!magcal_isfinite_f(m->z)) {
        return;
    }
    d = m->z - cc->sl_zp;
    cc->sl_nk++;
    /* every 4th pair (the noise is stationary) */
    if ((cc->sl_nk & 3u) == 0u && cc->sl_zn != 0u && t_ms - cc->sl_tp <= CONT_SL_PAIR_MS &&
        fabsf(d) <= CONT_SL_JUMP * (fabsf(m->x) + fabsf(m->y) + fabsf(m->z))) {
        /* half the mean square of successive differences: the noise (a slope or a turn moves raw z
         * by far less between two samples). No pair with a jump (a spike, garbage, a rail: the
         * start-up glitch made the first estimate 10^5 and left it 100 x too high minutes later),
         * and each difference clipped at 4 x the estimate's RMS; the first pair starts it */
        const float d2 = 0.5f * d * d;
        if (!(cc->sl_nz > 0.0f)) {
            cc->sl_nz = d2;
        } else {
            cc->sl_nz += magcal_cont_ema_w(t_ms - cc->sl_tp, CONT_SL_NOISE_MS) * (fminf(d2, 16.0f * cc->sl_nz) - cc->sl_nz);
        }
    }
    cc->sl_zp = m->z;
    cc->sl_tp = t_ms;
    cc->sl_zn = 1u;
}

void magcal_cont_slope(magcal_cont_t *cc, const magcal_cont_judge_t *j, uint32_t dt)
{
    if (cc->sl_ok != CONT_SL_DONE || !magcal_isfinite_f(j->u) || !(fabsf(j->rel) <= CONT_GLITCH_REL)) {
        return; /* (a glitch: no slope) */
    }
    if (cc->sl_tick <= UINT32_MAX - dt) {
        cc->sl_tick += dt;
    }
    cc->sl_half = (uint8_t)((cc->sl_half == 0u) ? 1u : 0u);
    if (cc->sl_half != 0u) {
        return; /* every 2nd sample (the drain's cost while a solve runs; 1 s is 20..50 of them) */
    }
    cc->sl_r += magcal_cont_ema_w(2u * dt, CONT_SL_SMOOTH_MS) * (cont_sl_res(cc, j->u, j->cs[0], j->cs[1]) - cc->sl_r);
    if (cc->sl_tick < CONT_SL_TICK_MS) {
        return; /* the slow measures every CONT_SL_TICK_MS (the drain's cost while a solve runs) */
    }
    {
        const uint32_t tk = cc->sl_tick;
        float v;
        cc->sl_tick = 0u;
        cc->sl_v += magcal_cont_ema_w(tk, CONT_SL_MS_MS) * (fminf(fabsf(cc->sl_r), CONT_SL_GATE) - cc->sl_v);
        v = CONT_SL_RMS * cc->sl_v;
        cc->sl_pk -= magcal_cont_ema_w(tk, CONT_SL_PK_MS) * cc->sl_pk;
        cc->sl_pk = fmaxf(cc->sl_pk, v * v);
        cc->sl_rp -= magcal_cont_ema_w(tk, CONT_SL_RP_MS) * cc->sl_rp;
        cc->sl_rp = fmaxf(cc->sl_rp, cc->sl_r * cc->sl_r);
        if (cc->sl_life <= UINT32_MAX - tk) {
            cc->sl_life += tk;
        }
    }
}

float magcal_cont_slope_err_deg(const magcal_cont_t *cc, float k_r)
{
    float e;
    if (cc->sl_ok != CONT_SL_DONE || cc->sl_life < CONT_SL_WARM_MS) {
        return INFINITY; /* nothing measured yet */
    }
    /* sl_vs and sl_pk are mean squares, sl_v a mean absolute residual; and the slope of the last
     * minutes where raw z showed it (the smoothed residual's square, peak held: a hill after a flat
     * stretch, seen at the first heading that shows it, held through the east and west headings
     * that do not; the mean takes minutes) */
    {
        const float v = CONT_SL_RMS * cc->sl_v;
        const float ms = fmaxf(fmaxf(cc->sl_vs, cc->sl_pk), fmaxf(v * v, cc->sl_rp));
        e = CONT_SL_PEAK * k_r * sqrtf(ms) * MAGCAL_DEG_PER_RAD_F;
    }
    if (cc->sl_life < CONT_SL_MS_MS && !(CONT_SL_PEAK * k_r * sqrtf(cc->sl_vs) * MAGCAL_DEG_PER_RAD_F <=
                                          CONT_SL_FLAT * cc->cfg.tilt_trust_deg)) {
        /* a store with slopes in it: the roads are not flat, and until the online mean has seen
         * its time constant of driving the slope of now is unknown (a store that looked level
         * enough was a slope's on 30-min seed 44: OK 5..7 deg off on a 2..3 deg grade until the
         * online measure rose 12 s later; seed 1 without this hold, 2,962 OK rows 8 deg off) */
        return INFINITY;
    }
    return e;
}
