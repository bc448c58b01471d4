/**
 * @file magcal_port.h
 * @brief The hardware seam of magcal: plain C prototypes each platform implements once.
 *
 * The library calls these functions and nothing else that touches hardware. A firmware links
 * exactly one implementation (chosen at link time): copy port/template/magcal_port_template.c,
 * fill in the I2C/SPI reads, and link it. Shipped implementations: port/replay (host, serves
 * recorded or generated samples), port/fake (scriptable test double), port/template (skeleton).
 *
 * Conventions every implementation must honour:
 * - axes: body frame x right, y forward, z up (rotate/negate raw sensor axes in the port);
 * - magnetometer: any fixed unit documented by the port (raw LSB, uT, gauss); the calibration is
 *   valid in that unit only;
 * - accelerometer: in g (1 g = 9.80665 m/s^2), reading about +1 on z when level and at rest;
 * - functions are called from one thread (the calibration loop) and must not block longer than
 *   one sensor sample period.
 *
 * Several magnetometers (docs/decisions/0008-multi-sensor-port.md): a port that serves more than
 * one magnetometer also implements magcal_port_mag_read_n(), indexed 0..MAGCAL_PORT_MAX_SENSORS-1,
 * where sensor 0 is the one magcal_port_mag_read() reads. Only magcal_calibrator_poll_n() calls
 * it, from its own translation unit: a single-sensor port that does not define it still links as
 * long as the firmware does not call magcal_calibrator_poll_n(). The accelerometer and the clock
 * stay single (one attitude reference and one time base per board).
 */
#ifndef MAGCAL_PORT_H
#define MAGCAL_PORT_H

#include <stdint.h>

#include "magcal/status.h"
#include "magcal/types.h"

#ifdef __cplusplus
extern "C" {
#endif

/**
 * @brief Read one magnetometer sample.
 * @param[out] out field in the port's documented unit, body frame x right / y forward / z up.
 *                 Written only on MAGCAL_OK.
 * @return MAGCAL_OK; MAGCAL_ERR_TIMEOUT when no new sample is ready (data-ready not set within
 *         the port's wait budget); MAGCAL_ERR_PORT on a bus or device error; MAGCAL_ERR_NO_DATA
 *         when the source is exhausted (replay ports only); MAGCAL_ERR_NULL for out == NULL.
 */
magcal_status_t magcal_port_mag_read(magcal_vec3_t *out);

/** Largest sensor index + 1 that magcal_calibrator_poll_n() accepts (override with -D). */
#ifndef MAGCAL_PORT_MAX_SENSORS
#define MAGCAL_PORT_MAX_SENSORS 4u
#endif

/**
 * @brief Read one sample of magnetometer `sensor` (multi-sensor ports only, see the file comment).
 * @param[in]  sensor 0..MAGCAL_PORT_MAX_SENSORS-1; 0 is the sensor of magcal_port_mag_read(), and
 *                    the two calls must serve the same stream for it.
 * @param[out] out    as magcal_port_mag_read(); written only on MAGCAL_OK.
 * @return as magcal_port_mag_read(); MAGCAL_ERR_ARG for a sensor the port does not have.
 */
magcal_status_t magcal_port_mag_read_n(uint8_t sensor, magcal_vec3_t *out);

/**
 * @brief Read one accelerometer sample.
 * @param[out] out specific force in g, body frame x right / y forward / z up. Written only on OK.
 * @return as magcal_port_mag_read().
 */
magcal_status_t magcal_port_accel_read(magcal_vec3_t *out);

/**
 * @brief Monotonic millisecond clock (wraps at 2^32 ms, about 49.7 days; compare with
 *        unsigned subtraction).
 */
uint32_t magcal_port_millis(void);

#ifdef __cplusplus
}
#endif

#endif /* MAGCAL_PORT_H */
