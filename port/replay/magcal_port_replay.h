/**
 * @file magcal_port_replay.h
 * @brief Host replay implementation of the HAL port: serves samples from caller-supplied arrays
 *        (or a CSV dump loaded into them, see replay_csv.h), with injectable read errors.
 *
 * The port is a link-time singleton, like any port: one replay source per program. Arrays are
 * borrowed, not copied; they must outlive the replay. Each read consumes one row; an injected
 * error also consumes its row (a failed bus read loses that sample, as on hardware).
 * The clock returns the row's timestamp when one is given, otherwise row index x period.
 */
#ifndef MAGCAL_PORT_REPLAY_H
#define MAGCAL_PORT_REPLAY_H

#include <stddef.h>
#include <stdint.h>

#include "magcal_port.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Most error injections that can be registered at once. */
#define MAGCAL_PORT_REPLAY_MAX_INJECT 64u

/**
 * @brief Start replaying. Resets the read positions and clears injections.
 * @param mag    n magnetometer rows (required).
 * @param accel  n accelerometer rows, or NULL (accel reads then return MAGCAL_ERR_NO_DATA).
 * @param t_ms   n timestamps in ms, or NULL (clock = row index x period_ms).
 * @param n      number of rows.
 * @param period_ms sample period used when t_ms is NULL.
 */
void magcal_port_replay_start(const magcal_vec3_t *mag, const magcal_vec3_t *accel,
                              const uint32_t *t_ms, size_t n, uint32_t period_ms);

/**
 * @brief Make the magnetometer read of row `row` fail with `st` (MAGCAL_ERR_PORT or
 *        MAGCAL_ERR_TIMEOUT typically). Returns 0, or -1 when the injection table is full.
 */
int magcal_port_replay_inject_mag(size_t row, magcal_status_t st);

/** @brief Make every `period`-th magnetometer read (rows period-1, 2*period-1, ...) fail. 0 disables. */
void magcal_port_replay_inject_mag_every(size_t period, magcal_status_t st);

/** @brief Row the next magnetometer read will serve. */
size_t magcal_port_replay_position(void);

#ifdef __cplusplus
}
#endif

#endif /* MAGCAL_PORT_REPLAY_H */
