/*
 * The reach decrease of the OPTICS ordering loop (algorithms.md 4.2), shared by the 2-D
 * (optics_order.c) and the 3-D (optics3.c) loop; included by those two files only. Not installed.
 * magcal_ocore_update() and magcal_ocore_sift_up() are plain `static`, not `inline` as the rest of
 * optics_core.h: with `inline`, GCC -O2 inlines them into the reach passes and magcal_optics_run
 * costs 1.9 % more instructions; their two internal copies are deviation D10
 * (docs/reliability.md).
 */
#ifndef MAGCAL_OPTICS_CORE_UPDATE_H
#define MAGCAL_OPTICS_CORE_UPDATE_H

#include <math.h>
#include <stddef.h>
#include <stdint.h>

#include "optics_core.h"

#if MAGCAL_CFG_ENABLE_OPTICS_CLASSIC
static void magcal_ocore_sift_up(magcal_ocore_t *o, size_t k0)
{
    size_t k = k0;
    uint16_t v = o->seeds[k];
    while (k > 0u) {
        size_t parent = (k - 1u) >> 1;
        uint16_t pv = o->seeds[parent];
        if (!magcal_ocore_key_less(o->reach, v, pv)) {
            break;
        }
        o->seeds[k] = pv;
        o->pos[pv] = (uint16_t)k;
        k = parent;
    }
    o->seeds[k] = v;
    o->pos[v] = (uint16_t)k;
}
#endif /* MAGCAL_CFG_ENABLE_OPTICS_CLASSIC */

/*
 * Reach decrease of unprocessed neighbour j of core point p to r (algorithms.md 4.2): callers
 * computed r = max(core(p), d) and checked r < reach[j] (strict: the first value set keeps ties).
 */
static void magcal_ocore_update(magcal_ocore_t *o, size_t p, size_t j, float r)
{
    float old = o->reach[j];
    o->reach[j] = r;
    if (o->pred != NULL) {
        o->pred[j] = (uint16_t)p;
    }
#if MAGCAL_CFG_ENABLE_OPTICS_CLASSIC
    if (o->mode == MAGCAL_OPTICS_CLASSIC) {
        if (o->pos[j] == MAGCAL_OCORE_POS_NONE) {
            o->seeds[o->n_seeds] = (uint16_t)j;
            o->n_seeds++;
            magcal_ocore_sift_up(o, o->n_seeds - 1u);
        } else {
            magcal_ocore_sift_up(o, o->pos[j]);
        }
    } else
#endif
#ifdef MAGCAL_OPTICS_BENCH_SORTED_LIST
    if (o->mode == MAGCAL_OPTICS_SORTED_LIST_) {
        if (old == INFINITY) {
            o->seeds[o->head + o->n_seeds] = (uint16_t)j;
            o->n_seeds++;
        }
        o->dirty = 1;
    } else
#endif
    if (old == INFINITY) {
        o->seeds[o->n_seeds] = (uint16_t)j;
        o->n_seeds++;
    } else {
        /* already a seed: its key decreased in place (the list is scanned, not a heap) */
    }
}

#endif /* MAGCAL_OPTICS_CORE_UPDATE_H */
