/*
 * magcal_calibrator_poll_n(): polling of one of several magnetometers (port/magcal_port.h,
 * docs/decisions/0008-multi-sensor-port.md). Its own translation unit: only a firmware that calls
 * it needs a port with magcal_port_mag_read_n().
 */
#include "magcal/calibrator.h"
#include "magcal_internal.h"
#include "magcal_port.h"

magcal_status_t magcal_calibrator_poll_n(magcal_calibrator_t *cal, uint8_t sensor)
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
    if (sensor >= MAGCAL_PORT_MAX_SENSORS) {
        return MAGCAL_ERR_ARG;
    }
    st = magcal_port_mag_read_n(sensor, &v);
    if (st != MAGCAL_OK) {
        return st;
    }
    p.x = v.x;
    p.y = v.y;
    return magcal_calibrator_push(cal, p);
}
