/*
 * Intake store: init, push (range check, spacing, cap per bin with newest-replaces-oldest),
 * centre control, the 2-D level band (its one-bin-per-push survey), snapshot and counters. The
 * binning geometry is in bins.c, the bounded survey / re-bin sweep in sweep.c, progress in
 * progress.c.
 */
#include <math.h>
#include <string.h>

#include "intake_internal.h"
#include "magcal_internal.h"

magcal_status_t magcal_intake_bins(const magcal_intake_cfg_t *cfg, uint16_t *bins)
{
    uint16_t n;
    if (cfg == NULL || bins == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (cfg->dims == 2u) {
        if (cfg->bins < 8u || cfg->bins > MAGCAL_INTAKE_MAX_BINS) {
            return MAGCAL_ERR_ARG;
        }
        *bins = cfg->bins;
        return MAGCAL_OK;
    }
    if (cfg->dims != 3u || cfg->bins < 4u || cfg->bins > MAGCAL_INTAKE_MAX_BANDS) {
        return MAGCAL_ERR_ARG;
    }
    n = magcal_intake_cells_3d(cfg->bins);
    if (n == 0u) {
        return MAGCAL_ERR_ARG;
    }
    *bins = n;
    return MAGCAL_OK;
}

magcal_status_t magcal_intake_init(magcal_intake_t *st, const magcal_intake_cfg_t *cfg,
                                   magcal_intake_slot_t *slots, size_t n_slots)
{
    uint16_t nb = 0u;
    magcal_status_t s;
    if (st == NULL || cfg == NULL || slots == NULL) {
        return MAGCAL_ERR_NULL;
    }
    s = magcal_intake_bins(cfg, &nb);
    if (s != MAGCAL_OK) {
        return s;
    }
    if (cfg->per_bin < 1u || cfg->per_bin > MAGCAL_INTAKE_MAX_PER_BIN || cfg->sweep_steps < 1u ||
        !magcal_isfinite_f(cfg->min_spacing_rel) || !(cfg->min_spacing_rel >= 0.0f && cfg->min_spacing_rel <= 0.5f) ||
        !magcal_isfinite_f(cfg->recentre_rel) || !(cfg->recentre_rel > 0.0f && cfg->recentre_rel <= 1.0f) ||
        !magcal_isfinite_f(cfg->range_limit) || !(cfg->range_limit >= 0.0f) ||
        !magcal_isfinite_f(cfg->level_band_rel) || !(cfg->level_band_rel >= 0.0f && cfg->level_band_rel <= 0.5f) ||
        !magcal_isfinite_f(cfg->tilt_limit_deg) || !(cfg->tilt_limit_deg >= 0.0f && cfg->tilt_limit_deg <= 30.0f) ||
        !magcal_isfinite_f(cfg->g_band_rel) || !(cfg->g_band_rel > 0.0f && cfg->g_band_rel <= 1.0f)) {
        return MAGCAL_ERR_ARG;
    }
    if (n_slots < (size_t)nb * (size_t)cfg->per_bin) {
        return MAGCAL_ERR_WORKSPACE;
    }
    (void)memset(st, 0, sizeof(*st));
    st->cfg = *cfg;
    st->slots = slots;
    if (cfg->dims == 3u) {
        (void)magcal_intake_build_mask(st, cfg->bins);
    }
    st->n_bins = nb;
    if (cfg->dims == 2u && cfg->tilt_limit_deg > 0.0f) {
        const float t = tanf(cfg->tilt_limit_deg * (MAGCAL_PI_F / 180.0f));
        st->tilt_tan2 = t * t; /* the push-side level test needs no trigonometry */
    }
    st->centre_source = (uint8_t)MAGCAL_INTAKE_CENTRE_NONE;
    magcal_intake_survey_clear(st);
    st->magic = INTAKE_MAGIC;
    return MAGCAL_OK;
}

int magcal_intake_insert(magcal_intake_t *st, uint16_t b, const magcal_vec3_t *m, uint32_t seq)
{
    const uint32_t per = st->cfg.per_bin;
    const uint32_t base = (uint32_t)b * per;
    uint32_t k;
    uint32_t oldest = base;
    uint32_t skip = 0u; /* INTAKE_SEQ_LEVEL: level samples are not candidates for replacement */
    if (st->count[b] < per) {
        st->slots[base + st->count[b]].m = *m;
        st->slots[base + st->count[b]].seq = seq;
        st->count[b]++;
        st->ctr.stored++;
        return 0;
    }
    for (k = base; k < base + per; ++k) {
        if ((st->slots[k].seq & INTAKE_SEQ_LEVEL) == 0u) {
            skip = INTAKE_SEQ_LEVEL; /* the bin holds a non-level sample: replace one of those */
            break;
        }
    }
    if (skip == 0u && (seq & INTAKE_SEQ_LEVEL) == 0u) {
        return 1; /* a non-level sample never replaces a level one: it is the one dropped */
    }
    if (st->centre_source == (uint8_t)MAGCAL_INTAKE_CENTRE_NONE) {
        /* no centre yet: a bin around the origin spans more of the ring than it will around the
         * centre, so keep its spread (replace the nearest sample) rather than its newest */
        float best = -1.0f;
        for (k = base; k < base + per; ++k) {
            const float dx = m->x - st->slots[k].m.x;
            const float dy = m->y - st->slots[k].m.y;
            const float dz = m->z - st->slots[k].m.z;
            const float d2 = dx * dx + dy * dy + dz * dz;
            if ((st->slots[k].seq & skip) == 0u && (best < 0.0f || d2 < best)) {
                best = d2;
                oldest = k;
            }
        }
    } else {
        uint32_t oldest_age = 0u;
        for (k = base; k < base + per; ++k) { /* ages modulo 2^31 pushes */
            const uint32_t age = (st->seq - st->slots[k].seq) & INTAKE_SEQ_MASK;
            if ((st->slots[k].seq & skip) == 0u && age >= oldest_age) {
                oldest_age = age;
                oldest = k;
            }
        }
    }
    st->slots[oldest].m = *m;
    st->slots[oldest].seq = seq;
    return 1;
}


/* 1 when the cut keeps sl: pushed at or after seq_limit, and on the ring (centre, ring_r) within
 * half its radius when ring_r > 0. */
static int intake_cut_keeps(const magcal_intake_slot_t *sl, uint32_t seq_limit, const magcal_vec2_t *centre,
                            float ring_r)
{
    const float dx = sl->m.x - centre->x;
    const float dy = sl->m.y - centre->y;
    const float dr = sqrtf(dx * dx + dy * dy) - ring_r;
    return ((sl->seq - seq_limit) & INTAKE_SEQ_MASK) < 0x40000000u && (!(ring_r > 0.0f) || fabsf(dr) <= 0.5f * ring_r)
               ? 1
               : 0;
}

void magcal_intake_drop_older(magcal_intake_t *st, uint32_t bin, uint32_t seq_limit, const magcal_vec2_t *centre,
                              float ring_r, magcal_vec2_t *out, size_t cap, uint32_t *n)
{
    const uint32_t base = bin * st->cfg.per_bin;
    const uint32_t cnt = st->count[bin];
    uint32_t keep = 0u;
    uint32_t k;
    for (k = 0u; k < cnt; ++k) {
        const magcal_intake_slot_t sl = st->slots[base + k];
        if (intake_cut_keeps(&sl, seq_limit, centre, ring_r) != 0) {
            st->slots[base + keep] = sl; /* compacted in place: the bin's order is kept */
            keep++;
            if (*n < cap) {
                out[*n].x = sl.m.x;
                out[*n].y = sl.m.y;
                (*n)++;
            }
        }
    }
    st->count[bin] = (uint8_t)keep;
    st->ctr.stored -= cnt - keep;
}

/* ---- 2-D level band (intake.h): the level model z = a + b cos + c sin of the direction from the
 * centre, fitted over the bins' median z by a survey of one bin per push. */
#define INTAKE_LV_MIN_BINS 8.0f  /* bins the level model needs */
/* cppcheck-suppress misra-c2012-2.3 ; deviation D4: a static assert is an unused typedef */
MAGCAL_STATIC_ASSERT(MAGCAL_INTAKE_MAX_PER_BIN <= 64u, intake_level_ring_mask_bits);
#define INTAKE_LV_RING_LO 0.7f   /* a bin's samples count on the ring only (as progress.c) */
#define INTAKE_LV_RING_HI 1.4f

static int intake_level_on(const magcal_intake_t *st)
{
    return st->cfg.dims == 2u && st->cfg.level_band_rel > 0.0f &&
           st->centre_source != (uint8_t)MAGCAL_INTAKE_CENTRE_NONE && st->radius > 0.0f;
}

static void intake_level_clear(magcal_intake_t *st)
{
    uint32_t k;
    for (k = 0u; k < 9u; ++k) {
        st->lv_s[k] = 0.0f;
    }
    st->lv_bin = 0u;
    st->lv_gen = st->gen;
}

int magcal_lv_solve(const float *q, float min_n, float det_rel, float *a)
{
    const float n = q[0];
    const float m00 = q[0];
    const float m01 = q[1];
    const float m02 = q[2];
    const float m11 = q[3];
    const float m12 = q[4];
    const float m22 = q[5];
    const float c00 = m11 * m22 - m12 * m12;
    const float c01 = m02 * m12 - m01 * m22;
    const float c02 = m01 * m12 - m02 * m11;
    const float det = m00 * c00 + m01 * c01 + m02 * c02;
    float r[3];
    if (!(n >= min_n) || !(det > det_rel * n * n * n)) {
        return 0;
    }
    {
        const float c11 = m00 * m22 - m02 * m02;
        const float c12 = m01 * m02 - m00 * m12;
        const float c22 = m00 * m11 - m01 * m01;
        r[0] = (c00 * q[6] + c01 * q[7] + c02 * q[8]) / det;
        r[1] = (c01 * q[6] + c11 * q[7] + c12 * q[8]) / det;
        r[2] = (c02 * q[6] + c12 * q[7] + c22 * q[8]) / det;
    }
    if (!(magcal_isfinite_f(r[0]) && magcal_isfinite_f(r[1]) && magcal_isfinite_f(r[2]))) {
        return 0;
    }
    a[0] = r[0];
    a[1] = r[1];
    a[2] = r[2];
    return 1;
}

/* The survey's solve: the 3 x 3 normal equations of z = a + b c + c s over the bins' medians
 * (magcal_lv_solve); a model only when the bins spread round the ring (a well-conditioned
 * matrix), else the previous model of this centre, if any, is kept. */
static void intake_level_solve(magcal_intake_t *st)
{
    if (magcal_lv_solve(st->lv_s, INTAKE_LV_MIN_BINS, 0.02f, st->lv_abc) != 0) {
        st->lv_ok = 1u;
        st->lv_ok_gen = st->lv_gen;
    }
}

/* Bit j of a bin's ring mask (j < per_bin <= 64). */
static uint64_t intake_bit(uint32_t j)
{
    const uint64_t one = 1u;
    return one << j;
}

/* One bin of the level survey: its samples on the ring, their lower-median z (rank count,
 * per_bin^2 compares on a ring mask: per_bin square roots, not per_bin^2) and mean direction enter
 * the sums; at the last bin the model is solved. */
static MAGCAL_NOINLINE void intake_level_step(magcal_intake_t *st)
{
    const uint32_t per = st->cfg.per_bin;
    const float r = st->radius;
    uint32_t b;
    uint32_t base;
    uint32_t k;
    uint32_t n = 0u;
    float dc = 0.0f;
    float ds = 0.0f;
    float zmed = 0.0f;
    uint32_t on = 0u; /* 1: the median was found */
    uint64_t ring = 0u; /* bit k - base: slot k is on the ring (per_bin <= MAGCAL_INTAKE_MAX_PER_BIN = 64) */
    if (intake_level_on(st) == 0) {
        return;
    }
    if (st->lv_gen != st->gen || st->lv_bin >= st->n_bins) {
        intake_level_clear(st); /* a new centre: the directions changed */
    }
    b = st->lv_bin;
    base = b * per;
    for (k = base; k < base + st->count[b]; ++k) {
        const float ux = st->slots[k].m.x - st->centre.x;
        const float uy = st->slots[k].m.y - st->centre.y;
        const float d = sqrtf(ux * ux + uy * uy);
        if (d >= INTAKE_LV_RING_LO * r && d <= INTAKE_LV_RING_HI * r) {
            dc += uy / d; /* heading convention atan2(-x, y): cos along y, sin along -x */
            ds -= ux / d;
            ring |= intake_bit(k - base);
            n++;
        }
    }
    if (n > 0u) {
        const uint32_t want = (n - 1u) / 2u; /* rank of the lower median among the ring samples */
        for (k = base; k < base + st->count[b] && on == 0u; ++k) {
            uint32_t below = 0u;
            uint32_t equal = 0u;
            uint32_t i;
            if ((ring & intake_bit(k - base)) == 0u) {
                continue;
            }
            for (i = base; i < base + st->count[b]; ++i) {
                if (i != k && (ring & intake_bit(i - base)) != 0u) {
                    if (st->slots[i].m.z < st->slots[k].m.z) {
                        below++;
                    } else if (st->slots[i].m.z == st->slots[k].m.z) {
                        equal++;
                    } else {
                        /* above */
                    }
                }
            }
            if (below <= want && below + equal >= want) {
                zmed = st->slots[k].m.z;
                on = 1u;
            }
        }
    }
    if (on != 0u) {
        const float nd = sqrtf(dc * dc + ds * ds);
        if (nd > 0.0f) {
            const float c = dc / nd;
            const float s = ds / nd;
            magcal_lv_sums(st->lv_s, zmed, c, s);
        }
    }
    st->lv_bin++;
    if (st->lv_bin >= st->n_bins) {
        intake_level_solve(st);
        intake_level_clear(st);
    }
}

/* 1 when m (bin b) lies outside the level band and its bin already holds half its cap. */
static MAGCAL_NOINLINE int intake_level_refuses(const magcal_intake_t *st, uint16_t b, const magcal_vec3_t *m)
{
    float ux;
    float uy;
    float d;
    float zhat;
    if (intake_level_on(st) == 0 || st->lv_ok == 0u || st->lv_ok_gen != st->gen ||
        2u * (uint32_t)st->count[b] < (uint32_t)st->cfg.per_bin) {
        return 0;
    }
    ux = m->x - st->centre.x;
    uy = m->y - st->centre.y;
    d = sqrtf(ux * ux + uy * uy);
    if (!(d > 0.0f)) {
        return 0;
    }
    zhat = st->lv_abc[0] + st->lv_abc[1] * (uy / d) - st->lv_abc[2] * (ux / d);
    return !(fabsf(m->z - zhat) <= st->cfg.level_band_rel * st->radius);
}

magcal_status_t magcal_intake_push(magcal_intake_t *st, const magcal_vec3_t *m,
                                   magcal_intake_outcome_t *outcome)
{
    return magcal_intake_push_tilt(st, m, MAGCAL_INTAKE_TILT_UNKNOWN, outcome);
}

magcal_status_t magcal_intake_push_tilt(magcal_intake_t *st, const magcal_vec3_t *m, magcal_intake_tilt_t tilt,
                                        magcal_intake_outcome_t *outcome)
{
    magcal_intake_outcome_t oc;
    magcal_status_t ret = MAGCAL_OK;
    if (st == NULL || m == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (st->magic != INTAKE_MAGIC) {
        return MAGCAL_ERR_NOT_INITIALISED;
    }
    st->ctr.pushed++;
    st->seq++;
    if (!magcal_isfinite_f(m->x) || !magcal_isfinite_f(m->y) || !magcal_isfinite_f(m->z)) {
        st->ctr.refused_nonfinite++;
        oc = MAGCAL_INTAKE_REFUSED_NONFINITE;
        ret = MAGCAL_ERR_NONFINITE;
    } else if (magcal_intake_saturated(&st->cfg, m) != 0) {
        st->ctr.refused_saturated++;
        oc = MAGCAL_INTAKE_REFUSED_SATURATED;
        ret = MAGCAL_ERR_SATURATED;
    } else {
        const uint16_t b = magcal_intake_bin_of(st, m);
        const uint32_t base = (uint32_t)b * st->cfg.per_bin;
        /* 2-D level preference: the slot's level bit (3-D: none) */
        const uint32_t lv = (st->cfg.dims == 2u && tilt == MAGCAL_INTAKE_TILT_LEVEL) ? INTAKE_SEQ_LEVEL : 0u;
        uint32_t n_level = 0u;
        int d3 = 0;
        float r = st->radius;
        float dmin2;
        uint32_t k;
        if (st->cfg.dims == 3u) {
            d3 = 1;
        }
        if (!(r > 0.0f)) { /* no radius yet: the sample's own distance from the centre */
            const float ux = m->x - st->centre.x;
            const float uy = m->y - st->centre.y;
            const float uz = (d3 != 0) ? (m->z - st->centre.z) : 0.0f;
            r = sqrtf(ux * ux + uy * uy + uz * uz);
        }
        dmin2 = st->cfg.min_spacing_rel * r;
        if (st->count[b] >= st->cfg.per_bin) {
            dmin2 *= 2.0f; /* a full bin: replacing needs twice the spacing (noise does not churn it) */
        }
        dmin2 *= dmin2;
        oc = MAGCAL_INTAKE_STORED;
        for (k = base; k < base + st->count[b]; ++k) {
            const float dx = m->x - st->slots[k].m.x;
            const float dy = m->y - st->slots[k].m.y;
            float d2 = dx * dx + dy * dy;
            if (d3 != 0) {
                const float dz = m->z - st->slots[k].m.z;
                d2 += dz * dz; /* 2-D: no term (adding 0 * 0 to a sum of squares changes no bit) */
            }
            if (d2 < dmin2) {
                oc = MAGCAL_INTAKE_REFUSED_SPACING;
                break;
            }
            n_level += ((st->slots[k].seq & INTAKE_SEQ_LEVEL) != 0u) ? 1u : 0u;
        }
        if (oc == MAGCAL_INTAKE_STORED && lv == 0u && n_level >= (uint32_t)st->cfg.per_bin) {
            oc = MAGCAL_INTAKE_REFUSED_TILTED; /* never over a level sample */
        }
        if (oc == MAGCAL_INTAKE_STORED && intake_level_refuses(st, b, m) != 0) {
            oc = MAGCAL_INTAKE_REFUSED_LEVEL;
        }
        if (oc == MAGCAL_INTAKE_REFUSED_SPACING) {
            st->ctr.refused_spacing++;
        } else if (oc == MAGCAL_INTAKE_REFUSED_TILTED) {
            st->ctr.refused_tilted++;
        } else if (oc == MAGCAL_INTAKE_REFUSED_LEVEL) {
            st->ctr.refused_level++;
        } else {
            if (magcal_intake_insert(st, b, m, (st->seq & INTAKE_SEQ_MASK) | lv) != 0) {
                st->ctr.replaced++;
                oc = MAGCAL_INTAKE_REPLACED;
            } else {
                st->ctr.added++;
            }
            st->ctr.stored_level += (lv != 0u) ? 1u : 0u;
        }
    }
    magcal_intake_sweep(st, st->cfg.sweep_steps);
    intake_level_step(st);
    if (outcome != NULL) {
        *outcome = oc;
    }
    return ret;
}

/* A new centre: every bin must be swept again (O(bins)). */
static void intake_recentre(magcal_intake_t *st)
{
    uint32_t b;
    for (b = 0u; b < st->n_bins; ++b) {
        st->bin_gen[b] = st->gen;
    }
    st->gen++;
    st->rebin_pending = 1u;
    st->ctr.recentres++;
}

void magcal_intake_recentre(magcal_intake_t *st, const magcal_vec3_t *c, float radius)
{
    st->centre = *c;
    if (st->cfg.dims == 2u) {
        st->centre.z = 0.0f;
    }
    st->radius = radius;
    intake_recentre(st);
}

magcal_status_t magcal_intake_set_centre(magcal_intake_t *st, const magcal_vec3_t *centre, float radius)
{
    if (st == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (st->magic != INTAKE_MAGIC) {
        return MAGCAL_ERR_NOT_INITIALISED;
    }
    if (centre == NULL) { /* keep the centre until the next survey moves it */
        st->centre_source = (uint8_t)MAGCAL_INTAKE_CENTRE_PROVISIONAL;
        return MAGCAL_OK;
    }
    if (!magcal_isfinite_f(centre->x) || !magcal_isfinite_f(centre->y) || !magcal_isfinite_f(centre->z) ||
        !magcal_isfinite_f(radius)) {
        return MAGCAL_ERR_NONFINITE;
    }
    if (!(radius > 0.0f)) {
        return MAGCAL_ERR_ARG;
    }
    st->centre_source = (uint8_t)MAGCAL_INTAKE_CENTRE_INSTALLED;
    magcal_intake_recentre(st, centre, radius);
    return MAGCAL_OK;
}

magcal_status_t magcal_intake_settle(magcal_intake_t *st)
{
    /* one sweep visits every slot once, plus one step per moved sample (<= slots) and per bin
     * jump: 2 slots + bins + 1 steps always complete a sweep. Two sweeps: the survey of the
     * current one is applied, a re-bin it starts is finished by the second. */
    uint32_t i;
    if (st == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (st->magic != INTAKE_MAGIC) {
        return MAGCAL_ERR_NOT_INITIALISED;
    }
    for (i = 0u; i < 3u; ++i) {
        const uint32_t target = st->sweeps + 1u;
        const uint32_t bound = 2u * magcal_intake_nslots(st) + (uint32_t)st->n_bins + 1u;
        uint32_t k;
        for (k = 0u; k < bound && st->sweeps != target; ++k) {
            magcal_intake_sweep(st, 1u);
        }
        if (i >= 1u && st->rebin_pending == 0u) {
            break;
        }
    }
    return MAGCAL_OK;
}

magcal_status_t magcal_intake_reset(magcal_intake_t *st)
{
    if (st == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (st->magic != INTAKE_MAGIC) {
        return MAGCAL_ERR_NOT_INITIALISED;
    }
    (void)memset(st->count, 0, sizeof(st->count));
    (void)memset(st->bin_gen, 0, sizeof(st->bin_gen));
    (void)memset(&st->ctr, 0, sizeof(st->ctr));
    (void)memset(&st->centre, 0, sizeof(st->centre));
    st->gen = 0u;
    st->radius = 0.0f;
    st->rebin_pending = 0u;
    st->centre_source = (uint8_t)MAGCAL_INTAKE_CENTRE_NONE;
    st->cursor = 0u;
    st->seq = 0u;
    (void)memset(&st->ref_c, 0, sizeof(st->ref_c));
    st->ref_r = 0.0f;
    st->ref_fit = 0u;
    st->lv_ok = 0u;
    intake_level_clear(st);
    magcal_intake_survey_clear(st);
    return MAGCAL_OK;
}

magcal_status_t magcal_intake_counters(const magcal_intake_t *st, magcal_intake_counters_t *out)
{
    if (st == NULL || out == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (st->magic != INTAKE_MAGIC) {
        return MAGCAL_ERR_NOT_INITIALISED;
    }
    *out = st->ctr;
    return MAGCAL_OK;
}

static magcal_status_t intake_snapshot(const magcal_intake_t *st, magcal_vec3_t *out3, magcal_vec2_t *out2,
                                       size_t cap, size_t *n)
{
    uint32_t b;
    size_t w = 0u;
    if (st == NULL || n == NULL || (out3 == NULL && out2 == NULL)) {
        return MAGCAL_ERR_NULL;
    }
    if (st->magic != INTAKE_MAGIC) {
        return MAGCAL_ERR_NOT_INITIALISED;
    }
    if (cap < (size_t)st->ctr.stored) {
        return MAGCAL_ERR_WORKSPACE;
    }
    for (b = 0u; b < st->n_bins; ++b) {
        const uint32_t base = b * (uint32_t)st->cfg.per_bin;
        uint32_t k;
        for (k = base; k < base + st->count[b]; ++k) {
            if (out3 != NULL) {
                out3[w] = st->slots[k].m;
            } else {
                out2[w].x = st->slots[k].m.x;
                out2[w].y = st->slots[k].m.y;
            }
            w++;
        }
    }
    *n = w;
    return MAGCAL_OK;
}

magcal_status_t magcal_intake_snapshot3(const magcal_intake_t *st, magcal_vec3_t *out, size_t cap, size_t *n)
{
    return intake_snapshot(st, out, NULL, cap, (out == NULL) ? NULL : n);
}

magcal_status_t magcal_intake_snapshot2(const magcal_intake_t *st, magcal_vec2_t *out, size_t cap, size_t *n)
{
    return intake_snapshot(st, NULL, out, cap, (out == NULL) ? NULL : n);
}
