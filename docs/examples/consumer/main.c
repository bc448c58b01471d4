/* Minimal firmware-style consumer of the installed magcal package: collect samples through the
 * port, calibrate, adopt, then turn raw samples into headings. Memory is static and sized with
 * the library's macros; nothing is allocated. */
#include <stdio.h>

#include "magcal.h"
#include "magcal/magcal_port.h"

#define CAPACITY 128u

static magcal_calibrator_t g_cal;
static magcal_vec2_t g_samples[CAPACITY];
static uint8_t g_work[MAGCAL_CALIBRATOR_WORKSPACE_LEN(CAPACITY)];
static magcal_cal2d_t g_stored = MAGCAL_CAL2D_IDENTITY; /* what the firmware keeps in flash */

int main(void)
{
    magcal_calibrator_cfg_t cfg = MAGCAL_CALIBRATOR_CFG_DEFAULT;
    magcal_cal_report_t report;
    magcal_status_t st;
    magcal_vec3_t m;
    float mag_deg = 0.0f;
    float true_deg = 0.0f;
    unsigned i;

    st = magcal_calibrator_init(&g_cal, &cfg, g_samples, CAPACITY, g_work, sizeof g_work);
    if (st != MAGCAL_OK) {
        return 1;
    }
    for (i = 0u; i < 400u && magcal_calibrator_count(&g_cal) < CAPACITY; ++i) {
        st = magcal_calibrator_poll(&g_cal); /* GATED (no new information) is not a fault */
        if (st != MAGCAL_OK && st != MAGCAL_ERR_GATED) {
            printf("poll: %s\n", magcal_status_str(st));
        }
    }
    st = magcal_calibrator_run(&g_cal, &g_stored, &report);
    printf("magcal %s: calibration %s, %u samples used, coverage %.0f deg, est. heading error %.2f deg\n",
           MAGCAL_VERSION_STRING, magcal_status_str(st), (unsigned)report.used,
           (double)report.coverage_deg, (double)report.est_heading_err_deg);
    if (st != MAGCAL_OK) {
        return 1;
    }
    if (magcal_port_mag_read(&m) != MAGCAL_OK) {
        return 1;
    }
    {
        magcal_vec2_t raw = {m.x, m.y};
        st = magcal_heading_compute(&g_stored, raw, -14.0f, &mag_deg, &true_deg);
    }
    printf("heading: magnetic %.1f deg, true %.1f deg (%s)\n", (double)mag_deg, (double)true_deg,
           magcal_status_str(st));
    return st == MAGCAL_OK ? 0 : 1;
}
