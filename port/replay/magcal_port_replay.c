/* Replay port: serves borrowed arrays through the HAL prototypes (see magcal_port_replay.h). */
#include "magcal_port_replay.h"

static struct {
    const magcal_vec3_t *mag;
    const magcal_vec3_t *accel;
    const uint32_t *t_ms;
    size_t n;
    uint32_t period_ms;
    size_t mag_pos;
    size_t acc_pos;
    size_t inj_row[MAGCAL_PORT_REPLAY_MAX_INJECT];
    magcal_status_t inj_st[MAGCAL_PORT_REPLAY_MAX_INJECT];
    size_t n_inj;
    size_t every;
    magcal_status_t every_st;
} g_rp;

void magcal_port_replay_start(const magcal_vec3_t *mag, const magcal_vec3_t *accel,
                              const uint32_t *t_ms, size_t n, uint32_t period_ms)
{
    g_rp.mag = mag;
    g_rp.accel = accel;
    g_rp.t_ms = t_ms;
    g_rp.n = (mag != NULL) ? n : 0u;
    g_rp.period_ms = period_ms;
    g_rp.mag_pos = 0u;
    g_rp.acc_pos = 0u;
    g_rp.n_inj = 0u;
    g_rp.every = 0u;
    g_rp.every_st = MAGCAL_OK;
}

int magcal_port_replay_inject_mag(size_t row, magcal_status_t st)
{
    if (g_rp.n_inj >= MAGCAL_PORT_REPLAY_MAX_INJECT) {
        return -1;
    }
    g_rp.inj_row[g_rp.n_inj] = row;
    g_rp.inj_st[g_rp.n_inj] = st;
    g_rp.n_inj++;
    return 0;
}

void magcal_port_replay_inject_mag_every(size_t period, magcal_status_t st)
{
    g_rp.every = period;
    g_rp.every_st = st;
}

size_t magcal_port_replay_position(void) { return g_rp.mag_pos; }

static magcal_status_t injected(size_t row)
{
    size_t i;
    for (i = 0u; i < g_rp.n_inj; ++i) {
        if (g_rp.inj_row[i] == row) {
            return g_rp.inj_st[i];
        }
    }
    if (g_rp.every != 0u && (row + 1u) % g_rp.every == 0u) {
        return g_rp.every_st;
    }
    return MAGCAL_OK;
}

magcal_status_t magcal_port_mag_read(magcal_vec3_t *out)
{
    size_t row;
    magcal_status_t st;
    if (out == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (g_rp.mag_pos >= g_rp.n) {
        return MAGCAL_ERR_NO_DATA;
    }
    row = g_rp.mag_pos++;
    st = injected(row);
    if (st != MAGCAL_OK) {
        return st;
    }
    *out = g_rp.mag[row];
    return MAGCAL_OK;
}

/* One replay source per program: sensor 0 only. */
magcal_status_t magcal_port_mag_read_n(uint8_t sensor, magcal_vec3_t *out)
{
    if (sensor != 0u) {
        return MAGCAL_ERR_ARG;
    }
    return magcal_port_mag_read(out);
}

magcal_status_t magcal_port_accel_read(magcal_vec3_t *out)
{
    if (out == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (g_rp.accel == NULL || g_rp.acc_pos >= g_rp.n) {
        return MAGCAL_ERR_NO_DATA;
    }
    *out = g_rp.accel[g_rp.acc_pos++];
    return MAGCAL_OK;
}

uint32_t magcal_port_millis(void)
{
    size_t row = (g_rp.mag_pos > 0u) ? g_rp.mag_pos - 1u : 0u;
    if (g_rp.t_ms != NULL && row < g_rp.n) {
        return g_rp.t_ms[row];
    }
    return (uint32_t)row * g_rp.period_ms;
}
