/*
 * Intake progress: coverage with the calibrator's definition (2-D: covered degrees = (sectors -
 * longest empty circular run) x width, the missing sector = that run), filled fraction, completion
 * and the filled-bin mask.
 *
 * A bin counts only the samples ON THE RING: at a distance from the centre within
 * [RING_LO, RING_HI] x R (R: the installed or fitted radius). A spike (the start-up glitch, a
 * driver's garbage burst) is stored like any sample until its bin fills, but the solver's density
 * filter rejects it; counted, one lone spike in an empty stretch split the longest gap and read
 * as 90 degrees the solve never found (gen_drive seed 3: live 270, solver 190). A provisional
 * centre far from the ring's (a short arc's small circle) puts the samples outside the band too,
 * so its bins do not read as coverage either. Until there is a radius (centre NONE) every sample
 * counts. O(slots): a squared distance per stored sample, up to the completion depth per bin; resumable
 * (magcal_intake_count_step) for the continuous calibrator's sliced step.
 */
#include <string.h>

#include "intake_internal.h"

#define RING_LO2 0.49f /* (0.7 R)^2: axis ratio 0.55 puts the ring within [0.74, 1.35] R */
#define RING_HI2 1.96f /* (1.4 R)^2 */
/* Weights of the resumable count (magcal_intake_count_step), estimated M4F instructions, measured
 * on the target (QEMU -icount shift=0, cont_trace.elf, tools/bench/cont_weights.py "count"). */
#define PROGRESS_W_BIN 80u    /* one bin: its loop, mask bit, depth */
#define PROGRESS_W_SAMPLE 30u /* one stored sample of it (the ring test; an upper bound: it stops at the depth) */

/* Samples of bin b on the ring (all of them before the store has a radius), counted up to
 * `limit` (the completion depth: more are not needed). */
static uint32_t ring_count(const magcal_intake_t *st, uint32_t b, uint32_t limit)
{
    const uint32_t base = b * (uint32_t)st->cfg.per_bin;
    const float r2 = st->radius * st->radius;
    uint32_t n = 0u;
    uint32_t k;
    if (!(st->radius > 0.0f) || st->centre_source == (uint8_t)MAGCAL_INTAKE_CENTRE_NONE) {
        return st->count[b];
    }
    for (k = base; k < base + st->count[b] && n < limit; ++k) {
        const float dx = st->slots[k].m.x - st->centre.x;
        const float dy = st->slots[k].m.y - st->centre.y;
        const float dz = (st->cfg.dims == 3u) ? st->slots[k].m.z - st->centre.z : 0.0f;
        const float d2 = dx * dx + dy * dy + dz * dz;
        if (d2 >= RING_LO2 * r2 && d2 <= RING_HI2 * r2) {
            n++;
        }
    }
    return n;
}

/* Filled-bin mask from the ring counts, resumable: bins *bin.. within `budget` estimated M4F
 * instructions (PROGRESS_W_BIN per bin + PROGRESS_W_SAMPLE per sample tested; at least one bin);
 * the filled bins into *filled, the completion depth (each bin counted up to `depth`, >= 1) into
 * *deep. Returns the instructions charged; the count is complete when *bin == st->n_bins. */
uint32_t magcal_intake_count_step(const magcal_intake_t *st, uint32_t *words, uint32_t depth, uint32_t *bin,
                                  uint32_t *filled, uint32_t *deep, uint32_t budget)
{
    uint32_t used = 0u;
    if (*bin == 0u) {
        (void)memset(words, 0, MAGCAL_INTAKE_MASK_WORDS(st->n_bins) * sizeof(words[0]));
        *filled = 0u;
        *deep = 0u;
    }
    while (*bin < st->n_bins && (used == 0u || used < budget)) {
        const uint32_t b = *bin;
        const uint32_t c = ring_count(st, b, depth);
        if (c != 0u) {
            words[b / 32u] |= (uint32_t)1u << (b % 32u);
            (*filled)++;
        }
        *deep += (c < depth) ? c : depth;
        used += PROGRESS_W_BIN + PROGRESS_W_SAMPLE * (uint32_t)st->count[b];
        (*bin)++;
    }
    return used;
}

/* The whole count (one code path with the resumable one). */
static uint32_t ring_mask(const magcal_intake_t *st, uint32_t *words, uint32_t depth, uint32_t *deep)
{
    uint32_t bin = 0u;
    uint32_t filled = 0u;
    (void)magcal_intake_count_step(st, words, depth, &bin, &filled, deep, UINT32_MAX);
    return filled;
}

static uint32_t is_set(const uint32_t *words, uint32_t b)
{
    return (words[b / 32u] >> (b % 32u)) & 1u;
}

/* Longest circular run of empty bins (nb when every bin is empty): length, and its first bin. */
static uint32_t longest_empty_run(const magcal_intake_t *st, const uint32_t *words, uint32_t *start)
{
    const uint32_t nb = st->n_bins;
    uint32_t best = 0u;
    uint32_t s0 = nb;
    uint32_t run = 0u;
    uint32_t run_start = 0u;
    uint32_t i;
    *start = 0u;
    for (i = 0u; i < nb; ++i) {
        if (is_set(words, i) != 0u) {
            s0 = i + 1u; /* scan from just after a filled bin: circular runs are contiguous */
            break;
        }
    }
    if (s0 == nb && (nb == 0u || is_set(words, nb - 1u) == 0u)) {
        return nb; /* no filled bin */
    }
    for (i = 0u; i < nb; ++i) {
        const uint32_t b = (s0 + i) % nb;
        if (is_set(words, b) == 0u) {
            if (run == 0u) {
                run_start = b;
            }
            run++;
            if (run > best) {
                best = run;
                *start = run_start;
            }
        } else {
            run = 0u;
        }
    }
    return best;
}

/* The completion depth of a bin: half its cap, rounded up. */
uint32_t magcal_intake_count_depth(const magcal_intake_t *st)
{
    return ((uint32_t)st->cfg.per_bin + 1u) / 2u;
}

void magcal_intake_progress_of(const magcal_intake_t *st, const uint32_t *words, uint32_t filled, uint32_t deep,
                               magcal_intake_progress_t *out)
{
    const uint32_t depth = magcal_intake_count_depth(st);
    (void)memset(out, 0, sizeof(*out));
    out->stored = st->ctr.stored;
    out->bins = st->n_bins;
    out->bins_filled = (uint16_t)filled;
    out->fill_fraction = (float)filled / (float)st->n_bins;
    out->completion_pct = 100.0f * (float)deep / ((float)st->n_bins * (float)depth);
    if (st->cfg.dims == 2u) {
        /* 360 x count / bins, not count x (360 / bins): at 85 bins the latter gives 360.00003 for
         * a full circle (an empty store with an installed centre read as more than one turn
         * missing: fuzz_cont); 360 x count is exact, so a full count gives exactly 360 */
        const float nbf = (float)st->n_bins;
        uint32_t start = 0u;
        const uint32_t run = longest_empty_run(st, words, &start);
        const uint32_t covered = (uint32_t)st->n_bins - run;
        out->coverage_deg = 360.0f * (float)covered / nbf;
        out->missing_start_deg = (run > 0u) ? 360.0f * (float)start / nbf : 0.0f;
        out->missing_width_deg = 360.0f * (float)run / nbf;
    } else {
        out->coverage_deg = 360.0f * out->fill_fraction;
    }
    out->centre = st->centre;
    out->radius = st->radius;
    out->centre_source = (magcal_intake_centre_t)st->centre_source;
    out->rebinning = st->rebin_pending;
}

magcal_status_t magcal_intake_progress(const magcal_intake_t *st, magcal_intake_progress_t *out)
{
    uint32_t words[MAGCAL_INTAKE_MASK_WORDS(MAGCAL_INTAKE_MAX_BINS)];
    uint32_t filled;
    uint32_t deep = 0u;
    if (st == NULL || out == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (st->magic != INTAKE_MAGIC) {
        return MAGCAL_ERR_NOT_INITIALISED;
    }
    filled = ring_mask(st, words, magcal_intake_count_depth(st), &deep);
    magcal_intake_progress_of(st, words, filled, deep, out);
    return MAGCAL_OK;
}

magcal_status_t magcal_intake_mask(const magcal_intake_t *st, uint32_t *words, size_t nwords)
{
    uint32_t deep = 0u;
    if (st == NULL || words == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (st->magic != INTAKE_MAGIC) {
        return MAGCAL_ERR_NOT_INITIALISED;
    }
    if (nwords < MAGCAL_INTAKE_MASK_WORDS(st->n_bins)) {
        return MAGCAL_ERR_WORKSPACE;
    }
    (void)ring_mask(st, words, 1u, &deep);
    return MAGCAL_OK;
}
