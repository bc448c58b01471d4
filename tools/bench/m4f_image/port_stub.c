/* Port of the footprint image: the "sensor" replays one recorded-like turn (48 samples of a
 * distorted ring, hard iron (300, -200), semi-axes 520 x 410 turned 30 deg, +/-2.5 noise) from
 * flash, as a firmware's driver would hand over register values. */
#include <stddef.h>

#include "magcal_port.h"

static const magcal_vec2_t k_turn[48] = {
    {750.3f, 62.5f},    {721.5f, 105.5f},   {684.4f, 142.1f},   {639.2f, 173.6f},
    {587.2f, 200.9f},   {530.5f, 222.9f},   {471.0f, 237.2f},   {410.2f, 242.0f},
    {348.3f, 237.5f},   {285.1f, 225.4f},   {220.9f, 208.0f},   {156.6f, 185.5f},
    {94.1f, 156.9f},    {35.6f, 120.5f},    {-16.8f, 76.6f},    {-62.5f, 27.1f},
    {-101.5f, -25.0f},  {-134.4f, -77.9f},  {-161.3f, -131.8f}, {-181.6f, -187.7f},
    {-194.0f, -245.9f}, {-197.0f, -304.9f}, {-190.0f, -361.6f}, {-173.4f, -413.5f},
    {-148.6f, -459.9f}, {-117.2f, -502.0f}, {-80.2f, -540.8f},  {-37.8f, -575.7f},
    {10.6f, -604.5f},   {65.0f, -624.9f},   {125.1f, -635.8f},  {189.0f, -638.5f},
    {254.5f, -635.0f},  {319.5f, -626.3f},  {382.7f, -611.3f},  {443.7f, -588.4f},
    {502.7f, -556.7f},  {559.7f, -517.5f},  {613.6f, -473.3f},  {662.8f, -426.5f},
    {705.1f, -377.6f},  {739.0f, -325.6f},  {764.0f, -269.5f},  {780.7f, -210.2f},
    {790.0f, -150.5f},  {792.5f, -93.3f},   {787.7f, -40.0f},   {774.8f, 9.9f},
};

static size_t g_next;
static uint32_t g_ms;

magcal_status_t magcal_port_mag_read(magcal_vec3_t *out)
{
    if (out == NULL) {
        return MAGCAL_ERR_NULL;
    }
    out->x = k_turn[g_next].x;
    out->y = k_turn[g_next].y;
    out->z = 400.0f;
    g_next = (g_next + 1u) % (sizeof k_turn / sizeof k_turn[0]);
    g_ms += 10u;
    return MAGCAL_OK;
}

magcal_status_t magcal_port_accel_read(magcal_vec3_t *out)
{
    if (out == NULL) {
        return MAGCAL_ERR_NULL;
    }
    out->x = 0.0f;
    out->y = 0.0f;
    out->z = 1.0f;
    return MAGCAL_OK;
}

uint32_t magcal_port_millis(void) { return g_ms; }
