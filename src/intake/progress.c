/*
 * Intake progress: coverage with the calibrator's definition (2-D: covered degrees = (sectors -
 * longest empty circular run) x width, the missing sector = that run), filled fraction, completion
 * and the filled-bin mask. O(bins).
 */
#include <string.h>

#include "intake_internal.h"

/* Longest circular run of empty bins (nb when every bin is empty): length, and its first bin. */
static uint32_t longest_empty_run(const magcal_intake_t *st, uint32_t *start)
{
    const uint32_t nb = st->n_bins;
    uint32_t best = 0u;
    uint32_t s0 = nb;
    uint32_t run = 0u;
    uint32_t run_start = 0u;
    uint32_t i;
    *start = 0u;
    for (i = 0u; i < nb; ++i) {
        if (st->count[i] != 0u) {
            s0 = i + 1u; /* scan from just after a filled bin: circular runs are contiguous */
            break;
        }
    }
    if (s0 == nb && (nb == 0u || st->count[nb - 1u] == 0u)) {
        return nb; /* no filled bin */
    }
    for (i = 0u; i < nb; ++i) {
        const uint32_t b = (s0 + i) % nb;
        if (st->count[b] == 0u) {
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

magcal_status_t magcal_intake_progress(const magcal_intake_t *st, magcal_intake_progress_t *out)
{
    uint32_t depth;
    uint32_t filled = 0u;
    uint32_t deep = 0u;
    uint32_t b;
    if (st == NULL || out == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (st->magic != INTAKE_MAGIC) {
        return MAGCAL_ERR_NOT_INITIALISED;
    }
    depth = ((uint32_t)st->cfg.per_bin + 1u) / 2u;
    for (b = 0u; b < st->n_bins; ++b) {
        const uint32_t c = st->count[b];
        filled += (c != 0u) ? 1u : 0u;
        deep += (c < depth) ? c : depth;
    }
    (void)memset(out, 0, sizeof(*out));
    out->stored = st->ctr.stored;
    out->bins = st->n_bins;
    out->bins_filled = (uint16_t)filled;
    out->fill_fraction = (float)filled / (float)st->n_bins;
    out->completion_pct = 100.0f * (float)deep / ((float)st->n_bins * (float)depth);
    if (st->cfg.dims == 2u) {
        const float w = 360.0f / (float)st->n_bins;
        uint32_t start = 0u;
        const uint32_t run = longest_empty_run(st, &start);
        const uint32_t covered = (uint32_t)st->n_bins - run;
        out->coverage_deg = (float)covered * w;
        out->missing_start_deg = (run > 0u) ? (float)start * w : 0.0f;
        out->missing_width_deg = (float)run * w;
    } else {
        out->coverage_deg = 360.0f * out->fill_fraction;
    }
    out->centre = st->centre;
    out->radius = st->radius;
    out->centre_source = (magcal_intake_centre_t)st->centre_source;
    out->rebinning = st->rebin_pending;
    return MAGCAL_OK;
}

magcal_status_t magcal_intake_mask(const magcal_intake_t *st, uint32_t *words, size_t nwords)
{
    uint32_t b;
    if (st == NULL || words == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (st->magic != INTAKE_MAGIC) {
        return MAGCAL_ERR_NOT_INITIALISED;
    }
    if (nwords < MAGCAL_INTAKE_MASK_WORDS(st->n_bins)) {
        return MAGCAL_ERR_WORKSPACE;
    }
    (void)memset(words, 0, MAGCAL_INTAKE_MASK_WORDS(st->n_bins) * sizeof(words[0]));
    for (b = 0u; b < st->n_bins; ++b) {
        if (st->count[b] != 0u) {
            words[b / 32u] |= (uint32_t)1u << (b % 32u);
        }
    }
    return MAGCAL_OK;
}
