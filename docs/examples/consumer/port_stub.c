/* The consumer's own port: a firmware supplies these three functions (see magcal_port.h).
 * This one serves a synthetic field so the example links and runs anywhere. */
#include <math.h>

#include "magcal/magcal_port.h"

static unsigned g_tick;

magcal_status_t magcal_port_mag_read(magcal_vec3_t *out)
{
    float a;
    if (out == 0) {
        return MAGCAL_ERR_NULL;
    }
    a = 0.1f * (float)(g_tick++ % 63u); /* about one turn every 63 samples */
    out->x = 120.0f + 300.0f * cosf(a);
    out->y = -40.0f + 250.0f * sinf(a);
    out->z = 400.0f;
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
