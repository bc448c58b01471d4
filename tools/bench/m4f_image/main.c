/* Footprint image of the 2-D pipeline as a firmware links it (tools/bench/run_bench.py sizes it):
 * collect through the port until the calibrator is READY, run the pipeline with the default
 * configuration (OPTICS improved + grid, automatic parameters, consensus), then compute one
 * heading. Capacity = MAGCAL_MAX_SAMPLES of the shipped configuration (1024). */
#include <stdint.h>

#include "magcal/calibrator.h"
#include "magcal/heading.h"
#include "magcal_port.h"

#define CAP ((size_t)MAGCAL_MAX_SAMPLES)

static magcal_calibrator_t g_cal;
static magcal_vec2_t g_buf[CAP];
static uint32_t g_work[(MAGCAL_CALIBRATOR_WORKSPACE_LEN(CAP) + 3u) / 4u];
static magcal_cal2d_t g_stored = MAGCAL_CAL2D_IDENTITY; /* a firmware restores it from flash */

volatile float g_heading_deg; /* results leave through volatiles so nothing is optimised away */
volatile int g_status;

int main(void)
{
    magcal_calibrator_cfg_t cfg = MAGCAL_CALIBRATOR_CFG_DEFAULT;
    magcal_cal_report_t rep;
    magcal_vec3_t m;
    magcal_vec2_t raw;
    float mag_deg = 0.0f;
    size_t i;
    magcal_status_t st = magcal_calibrator_init(&g_cal, &cfg, g_buf, CAP, g_work, sizeof g_work);

    for (i = 0u; st == MAGCAL_OK && i < CAP &&
                 magcal_calibrator_state(&g_cal) == MAGCAL_CALIBRATOR_COLLECTING;
         ++i) {
        st = magcal_calibrator_poll(&g_cal);
    }
    if (st == MAGCAL_OK) {
        st = magcal_calibrator_run(&g_cal, &g_stored, &rep);
    }
    if (st == MAGCAL_OK) {
        st = magcal_port_mag_read(&m);
    }
    if (st == MAGCAL_OK) {
        raw.x = m.x;
        raw.y = m.y;
        st = magcal_heading_compute(&g_stored, raw, 2.5f, &mag_deg, NULL);
    }
    g_heading_deg = mag_deg;
    g_status = (int)st;
    return st == MAGCAL_OK ? 0 : 1;
}
