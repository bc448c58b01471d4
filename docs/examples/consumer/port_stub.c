/* The consumer's own port: a firmware supplies these three functions (see magcal_port.h).
 * This one serves a synthetic field so the example links and runs anywhere. */
#include <math.h>

#include "magcal/magcal_port.h"

static unsigned g_tick;
static uint32_t g_lcg = 12345u;

/* A real sensor's noise, +-1.5 LSB uniform (deterministic): without it the samples repeat every
 * turn exactly, and the calibrator cannot tell their noise from its parameter error. */
static float noise(void)
{
    g_lcg = g_lcg * 1664525u + 1013904223u;
    return 3.0f * ((float)(g_lcg >> 8) / 16777216.0f) - 1.5f;
}

magcal_status_t magcal_port_mag_read(magcal_vec3_t *out)
{
    float a;
    if (out == 0) {
        return MAGCAL_ERR_NULL;
    }
    a = 0.1f * (float)(g_tick++ % 63u); /* about one turn every 63 samples */
    out->x = 120.0f + 300.0f * cosf(a) + noise();
    out->y = -40.0f + 250.0f * sinf(a) + noise();
    out->z = 400.0f + noise();
    return MAGCAL_OK;
}

magcal_status_t magcal_port_accel_read(magcal_vec3_t *out)
{
    if (out == 0) {
        return MAGCAL_ERR_NULL;
    }
    out->x = 0.0f;
    out->y = 0.0f;
    out->z = 1.0f;
    return MAGCAL_OK;
}

uint32_t magcal_port_millis(void) { return g_tick * 10u; }
