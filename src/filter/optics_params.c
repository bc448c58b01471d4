/*
 * The eps' rule of the 2-D automatic parameters (optics.h rule steps 2-4) around the robust centre
 * and radius of optics_centre.c: per-point angles, the ring band sorted by angle, links and core
 * requirements, the eps' choice, and (filter) each point's angular sector for the ring selection.
 * Resumable per point. State in optics_slice.h.
 */
#include <math.h>
#include <stddef.h>
#include <stdint.h>

#include "optics_slice.h"

/* The link and the core requirement of band point i (of m, sorted by angle): one visit. */
static MAGCAL_NOINLINE void ae_link(magcal_o2_ae_t *e, const magcal_vec2_t *pts,
                                    const uint16_t *idx, size_t m, size_t i, const uint8_t *rep,
                                    float *b)
{
    const magcal_vec2_t *p0 = &pts[idx[i]];
    float near[2u * AUTO_WIN];
    float l = INFINITY;
    size_t q;
    size_t t;
    size_t u;
    /* shortest way across the step i -> i+1 that bypasses up to AUTO_WIN - 1 points */
    for (q = 0; q < AUTO_WIN; ++q) {
        for (t = 1u; q + t <= AUTO_WIN; ++t) {
            float dd = magcal_o2_dist(&pts[idx[(i + m - q) % m]], &pts[idx[(i + t) % m]]);
            l = dd < l ? dd : l;
        }
    }
    if (l > e->link1) {
        e->link2 = e->link1;
        e->link1 = l;
    } else if (l > e->link2) {
        e->link2 = l;
    } else {
        /* neither of the two longest links */
    }
    if ((rep[idx[i]] & AUTO_CAPPED) == 0u) {
        return; /* the core quantile counts a clump as K samples (mean cell occupancy) */
    }
    /* core requirement: (MinPts-1)-th nearest of the AUTO_WIN angular neighbours each side */
    for (q = 1u; q <= AUTO_WIN; ++q) {
        near[2u * q - 2u] = magcal_o2_dist(p0, &pts[idx[(i + m - q) % m]]);
        near[2u * q - 1u] = magcal_o2_dist(p0, &pts[idx[(i + q) % m]]);
    }
    for (t = 1u; t < (size_t)AUTO_WIN * 2u; ++t) { /* insertion sort of 8 values */
        float v = near[t];
        for (u = t; u > 0u; --u) {
            if (!(near[u - 1u] > v)) {
                break;
            }
            near[u] = near[u - 1u];
        }
        near[u] = v;
    }
    b[e->nq] = near[AUTO_MIN_PTS - 2u];
    e->nq++;
}

/* eps' = 1.5 * max(second largest link, core quantile), clamped to [R/256, R]. */
static float ae_eps(float link2, float coreq, float rad)
{
    float e = AUTO_SAFETY * (link2 > coreq ? link2 : coreq);
    if (e < AUTO_MIN_REL * rad) {
        e = AUTO_MIN_REL * rad;
    }
    if (e > AUTO_MAX_REL * rad) {
        e = AUTO_MAX_REL * rad;
    }
    return e;
}

/* AE_ANGLES from point i: angles around c into a[], ring band members into idx[] (own frame).
 * Returns the next point. */
static MAGCAL_NOINLINE size_t ae_angles(magcal_o2_ae_t *e, const magcal_vec2_t *pts, size_t n,
                                        uint8_t *w, const float cr[3], size_t i0, int32_t *rem)
{
    float *a = (float *)(void *)w;
    uint16_t *idx = (uint16_t *)(void *)(w + 4u * n);
    const float lo = cr[2] - AUTO_BAND * cr[2];
    const float hi = cr[2] + AUTO_BAND * cr[2];
    size_t m = e->m;
    size_t i = i0;
    int32_t r = *rem;
    for (; i < n && r > 0; ++i) {
        float dx = pts[i].x - cr[0];
        float dy = pts[i].y - cr[1];
        float rr = sqrtf(dx * dx + dy * dy);
        a[i] = magcal_atan2f(dy, dx);
        if (rr >= lo && rr <= hi) {
            idx[m] = (uint16_t)i;
            ++m;
        }
        CHARGE(r, W_ANGLE);
    }
    e->m = (uint16_t)m;
    *rem = r;
    return i;
}

/* AE_SECTORS from point i: each point's sector (-1 outside the band) from the angles a[]. */
static MAGCAL_NOINLINE size_t ae_sectors(const magcal_vec2_t *pts, size_t n, const float *a,
                                         const float cr[3], int16_t *sectors, size_t i0,
                                         int32_t *rem)
{
    const float lo = cr[2] - AUTO_BAND * cr[2];
    const float hi = cr[2] + AUTO_BAND * cr[2];
    size_t i = i0;
    int32_t r = *rem;
    for (; i < n && r > 0; ++i) {
        float dx = pts[i].x - cr[0];
        float dy = pts[i].y - cr[1];
        float rr = sqrtf(dx * dx + dy * dy);
        int16_t sec = -1;
        if (rr >= lo && rr <= hi) {
            float f = (a[i] + AUTO_PI) * ((float)AUTO_SECTORS / (2.0f * AUTO_PI));
            int32_t k = (int32_t)f;
            k = k < 0 ? 0 : (k > (int32_t)AUTO_SECTORS - 1 ? (int32_t)AUTO_SECTORS - 1 : k);
            sec = (int16_t)k;
        }
        sectors[i] = sec;
        CHARGE(r, W_SECTOR);
    }
    *rem = r;
    return i;
}

/* Returns 1 when done (*st: MAGCAL_OK with *eps_prime, or MAGCAL_ERR_DEGENERATE), else 0. */
MAGCAL_NOINLINE int magcal_o2_ae_run(magcal_o2_ae_t *e, const magcal_vec2_t *pts, size_t n,
                                     uint8_t *w, const float cr[3], float *eps_prime,
                                     magcal_status_t *st, int32_t *rem)
{
    int16_t *const sectors = e->sectors != 0u ? (int16_t *)(void *)(w + 4u * n) : NULL;
    float *a = (float *)(void *)w;
    uint16_t *idx = (uint16_t *)(void *)(w + 4u * n);
    float *b = (float *)(void *)(w + AUTO_B_OFF(n));
    const uint8_t *rep = w + AUTO_REP_OFF(n);
    size_t i = e->i;
    int32_t r = *rem;
    int paused = 0;
    /* cppcheck-suppress misra-c2012-15.4 ; deviation D13: a resumable loop leaves at its pause point and at its phase end */
    while (paused == 0 && e->st != (uint8_t)AE_DONE) {
        if (r <= 0) {
            paused = 1;
            break;
        }
        if (e->st == (uint8_t)AE_ANGLES) {
            i = ae_angles(e, pts, n, w, cr, i, &r);
            if (i < n) {
                paused = 1;
                break;
            }
            if (e->m < 2u * AUTO_WIN + 2u) { /* the cyclic windows need distinct neighbours */
                *st = MAGCAL_ERR_DEGENERATE;
                *rem = r;
                return 1;
            }
            magcal_o2_hsort_begin(&e->u.hs, e->m);
            e->st = (uint8_t)AE_SORT;
        } else if (e->st == (uint8_t)AE_SORT) {
            if (magcal_o2_hsort_run(&e->u.hs, idx, a, &r) == 0) {
                paused = 1;
                break;
            }
            i = 0u;
            e->st = (uint8_t)AE_LINKS;
        } else if (e->st == (uint8_t)AE_LINKS) {
            const size_t m = e->m;
            for (; i < m && r > 0; ++i) {
                ae_link(e, pts, idx, m, i, rep, b);
                CHARGE(r, W_LINK);
            }
            if (i < m) {
                paused = 1;
                break;
            }
            e->st = (uint8_t)AE_SECTORS; /* via the quantile when there is one */
            if (e->nq > 0u) {
                const size_t last = (size_t)e->nq - 1u;
                const float qpos = AUTO_CORE_Q * (float)last;
                magcal_o2_sel_begin(&e->u.sel, e->nq, (size_t)qpos);
                e->st = (uint8_t)AE_SEL;
            } else {
                *eps_prime = ae_eps(e->link2, 0.0f, cr[2]); /* no core requirement counted */
            }
            i = 0u;
        } else if (e->st == (uint8_t)AE_SEL) {
            float coreq;
            if (magcal_o2_sel_run(&e->u.sel, b, &r) == 0) {
                paused = 1;
                break;
            }
            coreq = b[e->u.sel.k];
            *eps_prime = ae_eps(e->link2, coreq, cr[2]);
            i = 0u;
            e->st = (uint8_t)AE_SECTORS;
        } else {
            /* AE_SECTORS: a[] still holds the angles; sectors overlay idx (no longer needed) */
            if (sectors == NULL) {
                e->st = (uint8_t)AE_DONE;
                break;
            }
            i = ae_sectors(pts, n, a, cr, sectors, i, &r);
            if (i < n) {
                paused = 1;
                break;
            }
            e->st = (uint8_t)AE_DONE;
        }
    }
    e->i = (uint16_t)i;
    *rem = r;
    if (paused != 0) {
        return 0;
    }
    *st = MAGCAL_OK;
    return 1;
}

