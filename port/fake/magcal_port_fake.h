/**
 * @file magcal_port_fake.h
 * @brief Hand-written, scriptable double of the HAL port for unit tests.
 *
 * Tests queue results (a sample or a status) per channel; each read pops one. An empty queue
 * answers MAGCAL_ERR_NO_DATA. The clock advances by a configurable step on every millis() call.
 * Magnetometers 0..MAGCAL_PORT_FAKE_SENSORS-1 have one queue each (magcal_port_mag_read_n());
 * the single-sensor calls are sensor 0.
 */
#ifndef MAGCAL_PORT_FAKE_H
#define MAGCAL_PORT_FAKE_H

#include <stddef.h>
#include <stdint.h>

#include "magcal_port.h"

#ifdef __cplusplus
extern "C" {
#endif

#define MAGCAL_PORT_FAKE_QUEUE_LEN 4096u
/** Magnetometers the fake serves (indices 0 and 1; other indices answer MAGCAL_ERR_ARG). */
#define MAGCAL_PORT_FAKE_SENSORS 2u

/** Reset both queues, the call counters and the clock (to 0 ms, step 10 ms). */
void magcal_port_fake_reset(void);
/** Queue a good magnetometer sample. Returns 0, or -1 when the queue is full. */
int magcal_port_fake_push_mag(magcal_vec3_t v);
/** Queue a magnetometer failure (e.g. MAGCAL_ERR_PORT, MAGCAL_ERR_TIMEOUT). */
int magcal_port_fake_push_mag_status(magcal_status_t st);
/** Queue a good sample of magnetometer `sensor`. Returns 0, or -1 (queue full, no such sensor). */
int magcal_port_fake_push_mag_n(uint8_t sensor, magcal_vec3_t v);
/** Queue a failure of magnetometer `sensor`. Returns 0, or -1. */
int magcal_port_fake_push_mag_status_n(uint8_t sensor, magcal_status_t st);
/** Queue a good accelerometer sample (g). */
int magcal_port_fake_push_accel(magcal_vec3_t v);
/** Queue an accelerometer failure. */
int magcal_port_fake_push_accel_status(magcal_status_t st);
/** Clock step per millis() call. */
void magcal_port_fake_set_clock_step(uint32_t step_ms);
/** Number of magcal_port_mag_read() calls since reset. */
size_t magcal_port_fake_mag_calls(void);
/** Number of reads of magnetometer `sensor` since reset (0 for an unknown sensor). */
size_t magcal_port_fake_mag_calls_n(uint8_t sensor);
/** Number of magcal_port_accel_read() calls since reset. */
size_t magcal_port_fake_accel_calls(void);

#ifdef __cplusplus
}
#endif

#endif /* MAGCAL_PORT_FAKE_H */
