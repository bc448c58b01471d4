/* Scriptable port double (see magcal_port_fake.h). Test code only: uses file-scope state. */
#include "magcal_port_fake.h"

typedef struct {
    magcal_vec3_t v[MAGCAL_PORT_FAKE_QUEUE_LEN];
    magcal_status_t st[MAGCAL_PORT_FAKE_QUEUE_LEN];
    size_t head;
    size_t tail;
    size_t calls;
} fake_queue_t;

static fake_queue_t g_mag[MAGCAL_PORT_FAKE_SENSORS]; /* one queue per magnetometer */
static fake_queue_t g_acc;
static uint32_t g_now;
static uint32_t g_step = 10u;

static void q_reset(fake_queue_t *q)
{
    q->head = 0u;
    q->tail = 0u;
    q->calls = 0u;
}

static int q_push(fake_queue_t *q, magcal_vec3_t v, magcal_status_t st)
{
    if (q->tail >= MAGCAL_PORT_FAKE_QUEUE_LEN) {
        return -1;
    }
    q->v[q->tail] = v;
    q->st[q->tail] = st;
    q->tail++;
    return 0;
}

static magcal_status_t q_pop(fake_queue_t *q, magcal_vec3_t *out)
{
    magcal_status_t st;
    q->calls++;
    if (out == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (q->head >= q->tail) {
        return MAGCAL_ERR_NO_DATA;
    }
    st = q->st[q->head];
    if (st == MAGCAL_OK) {
        *out = q->v[q->head];
    }
    q->head++;
    return st;
}

void magcal_port_fake_reset(void)
{
    size_t i;
    for (i = 0u; i < MAGCAL_PORT_FAKE_SENSORS; ++i) {
        q_reset(&g_mag[i]);
    }
    q_reset(&g_acc);
    g_now = 0u;
    g_step = 10u;
}

int magcal_port_fake_push_mag(magcal_vec3_t v) { return magcal_port_fake_push_mag_n(0u, v); }

int magcal_port_fake_push_mag_status(magcal_status_t st)
{
    return magcal_port_fake_push_mag_status_n(0u, st);
}

int magcal_port_fake_push_mag_n(uint8_t sensor, magcal_vec3_t v)
{
    if (sensor >= MAGCAL_PORT_FAKE_SENSORS) {
        return -1;
    }
    return q_push(&g_mag[sensor], v, MAGCAL_OK);
}

int magcal_port_fake_push_mag_status_n(uint8_t sensor, magcal_status_t st)
{
    magcal_vec3_t z = {0.0f, 0.0f, 0.0f};
    if (sensor >= MAGCAL_PORT_FAKE_SENSORS) {
        return -1;
    }
    return q_push(&g_mag[sensor], z, st);
}

int magcal_port_fake_push_accel(magcal_vec3_t v) { return q_push(&g_acc, v, MAGCAL_OK); }

int magcal_port_fake_push_accel_status(magcal_status_t st)
{
    magcal_vec3_t z = {0.0f, 0.0f, 0.0f};
    return q_push(&g_acc, z, st);
}

void magcal_port_fake_set_clock_step(uint32_t step_ms) { g_step = step_ms; }
size_t magcal_port_fake_mag_calls(void) { return g_mag[0].calls; }

size_t magcal_port_fake_mag_calls_n(uint8_t sensor)
{
    return sensor < MAGCAL_PORT_FAKE_SENSORS ? g_mag[sensor].calls : 0u;
}
size_t magcal_port_fake_accel_calls(void) { return g_acc.calls; }

magcal_status_t magcal_port_mag_read(magcal_vec3_t *out) { return q_pop(&g_mag[0], out); }

magcal_status_t magcal_port_mag_read_n(uint8_t sensor, magcal_vec3_t *out)
{
    if (sensor >= MAGCAL_PORT_FAKE_SENSORS) {
        return MAGCAL_ERR_ARG; /* a sensor this board does not have; no queue is touched */
    }
    return q_pop(&g_mag[sensor], out);
}
magcal_status_t magcal_port_accel_read(magcal_vec3_t *out) { return q_pop(&g_acc, out); }

uint32_t magcal_port_millis(void)
{
    uint32_t t = g_now;
    g_now += g_step;
    return t;
}
