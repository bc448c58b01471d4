/*
 * Intake bins: direction of a sample around the centre -> bin index.
 * 2-D: heading sectors of (x, y), angle atan2(-x, y) in [0, 360) (the calibrator's convention).
 * 3-D: an equal-area "igloo" mask: `bands` latitude bands of equal colatitude height pi/bands,
 * band b split into round(2 bands sin(colatitude of its middle)) cells of equal longitude width,
 * so every cell is close to a square of side pi/bands (area 4 pi / cells within a few per cent).
 */
#include <math.h>

#include "intake_internal.h"
#include "magcal_internal.h"

/* Cells of band b of a `bands`-band mask. */
static uint32_t band_cells(uint32_t b, uint32_t bands)
{
    const float mid = ((float)b + 0.5f) * MAGCAL_PI_F / (float)bands;
    const float w = 2.0f * (float)bands * sinf(mid) + 0.5f;
    const uint32_t cells = (uint32_t)w;
    return (cells < 1u) ? 1u : cells;
}

uint16_t magcal_intake_cells_3d(uint16_t bands)
{
    uint32_t total = 0u;
    uint32_t b;
    if (bands < 1u || bands > MAGCAL_INTAKE_MAX_BANDS) {
        return 0u;
    }
    for (b = 0u; b < bands; ++b) {
        total += band_cells(b, bands);
    }
    return (total <= MAGCAL_INTAKE_MAX_BINS) ? (uint16_t)total : 0u;
}

uint16_t magcal_intake_build_mask(magcal_intake_t *st, uint16_t bands)
{
    uint32_t total = 0u;
    uint16_t b;
    if (bands < 1u || bands > MAGCAL_INTAKE_MAX_BANDS) {
        return 0u;
    }
    for (b = 0u; b < bands; ++b) {
        const uint32_t cells = band_cells(b, bands);
        st->band_start[b] = (uint16_t)total;
        st->band_cos[b] = cosf((float)b * MAGCAL_PI_F / (float)bands);
        total += cells;
    }
    st->band_start[bands] = (uint16_t)total;
    st->band_cos[bands] = -1.0f;
    st->band_cos[0] = 1.0f;
    st->n_bands = bands;
    return (total <= MAGCAL_INTAKE_MAX_BINS) ? (uint16_t)total : 0u;
}

/* 3-D: the cell of the igloo mask holding direction (ux, uy, uz) from the centre. */
static uint16_t bin_of_cell(const magcal_intake_t *st, float ux, float uy, float uz)
{
    const float r = sqrtf(ux * ux + uy * uy + uz * uz);
    const float c = (r > 0.0f) ? uz / r : 1.0f;
    uint32_t lo = 0u;
    uint32_t hi = st->n_bands; /* band_cos[lo] >= c > band_cos[hi] */
    uint32_t cells;
    uint32_t k;
    float a;
    while (hi - lo > 1u) { /* at most log2(MAGCAL_INTAKE_MAX_BANDS) + 1 steps */
        const uint32_t mid = (lo + hi) / 2u;
        if (c <= st->band_cos[mid]) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    cells = (uint32_t)st->band_start[lo + 1u] - (uint32_t)st->band_start[lo];
    a = atan2f(uy, ux) * (1.0f / (2.0f * MAGCAL_PI_F));
    if (a < 0.0f) {
        a += 1.0f;
    }
    k = (uint32_t)(a * (float)cells);
    k = (k >= cells) ? cells - 1u : k;
    return (uint16_t)((uint32_t)st->band_start[lo] + k);
}

uint16_t magcal_intake_bin_of(const magcal_intake_t *st, const magcal_vec3_t *m)
{
    const float ux = m->x - st->centre.x;
    const float uy = m->y - st->centre.y;
    if (st->cfg.dims == 2u) {
        float a = atan2f(-ux, uy) * (1.0f / (2.0f * MAGCAL_PI_F)); /* turns, (-0.5, 0.5] */
        uint32_t k;
        if (a < 0.0f) {
            a += 1.0f;
        }
        k = (uint32_t)(a * (float)st->n_bins);
        return (k >= st->n_bins) ? (uint16_t)(st->n_bins - 1u) : (uint16_t)k;
    }
    return bin_of_cell(st, ux, uy, m->z - st->centre.z);
}
