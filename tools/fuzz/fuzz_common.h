/*
 * Shared helpers of the libFuzzer harnesses (tools/fuzz/README.md). Host only.
 * FUZZ_CHECK aborts with a message: libFuzzer reports the abort as a crash and saves the input.
 */
#ifndef MAGCAL_FUZZ_COMMON_H
#define MAGCAL_FUZZ_COMMON_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "magcal/status.h"

#define FUZZ_CHECK(cond, what)                                                                     \
    do {                                                                                           \
        if (!(cond)) {                                                                             \
            fprintf(stderr, "FUZZ INVARIANT FAILED %s:%d: %s (%s)\n", __FILE__, __LINE__, (what),  \
                    #cond);                                                                        \
            abort();                                                                               \
        }                                                                                          \
    } while (0)

/** Byte reader over the fuzz input: reads past the end give zeros. */
typedef struct {
    const uint8_t *p;
    size_t len;
    size_t pos;
} fuzz_in_t;

static inline uint8_t fuzz_u8(fuzz_in_t *in)
{
    return in->pos < in->len ? in->p[in->pos++] : 0u;
}

static inline uint16_t fuzz_u16(fuzz_in_t *in)
{
    uint16_t lo = fuzz_u8(in);
    return (uint16_t)(lo | (uint16_t)(fuzz_u8(in) << 8));
}

/** Raw IEEE-754 bits: every float including NaN payloads, +/-Inf, subnormals, -0. */
static inline float fuzz_f32(fuzz_in_t *in)
{
    uint32_t b = 0u;
    float f;
    unsigned k;
    for (k = 0u; k < 4u; ++k) {
        b |= (uint32_t)fuzz_u8(in) << (8u * k);
    }
    memcpy(&f, &b, sizeof f);
    return f;
}

static inline size_t fuzz_left(const fuzz_in_t *in)
{
    return in->len - in->pos;
}

/** Status is one of the enum's values (no garbage codes). */
static inline int fuzz_status_known(magcal_status_t st)
{
    return st <= MAGCAL_OK && st >= MAGCAL_ERR_GATED;
}

#endif /* MAGCAL_FUZZ_COMMON_H */
