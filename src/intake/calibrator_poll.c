/*
 * magcal_calibrator_poll(): a calibrator function that calls the HAL port (with
 * magcal_calibrator_poll_n(), src/intake/calibrator_poll_n.c). Kept in its own translation unit so a
 * program that only pushes samples does not need a port at link time, and a single-sensor port
 * (no magcal_port_mag_read_n()) links with it.
 */
#include "magcal/calibrator.h"
#include "magcal_internal.h"
#include "magcal_port.h"

magcal_status_t magcal_calibrator_poll(magcal_calibrator_t *cal)
{
    magcal_vec3_t v;
    magcal_vec2_t p;
    magcal_status_t st;
    if (cal == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (cal->magic != MAGCAL_CALIBRATOR_MAGIC) {
        return MAGCAL_ERR_NOT_INITIALISED;
    }
    st = magcal_port_mag_read(&v);
    if (st != MAGCAL_OK) {
        return st;
    }
    p.x = v.x;
    p.y = v.y;
    return magcal_calibrator_push(cal, p);
}

