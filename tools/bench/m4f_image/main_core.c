/* Footprint image of the seed-equivalent 2-D core (no calibrator object, no consensus stage):
 * read samples through the port, OPTICS filter with automatic parameters, least-squares ellipse
 * fit of the inliers, correction, one heading. Sized next to pipeline2d.elf by run_bench.py to
 * show what the calibrator and consensus stages add. Capacity = MAGCAL_MAX_SAMPLES (1024). */
#include <stdint.h>

#include "magcal/ellipse.h"
#include "magcal/heading.h"
#include "magcal/optics.h"
#include "magcal_port.h"

#define CAP ((size_t)MAGCAL_MAX_SAMPLES)
#define N_COLLECT 48u

static magcal_vec2_t g_pts[CAP];
static uint8_t g_inlier[CAP];
static uint32_t g_work[(MAGCAL_OPTICS_FILTER_WORKSPACE_LEN(CAP) + 3u) / 4u];

volatile float g_heading_deg;
volatile int g_status;

int main(void)
{
    magcal_optics_cfg_t cfg = MAGCAL_OPTICS_CFG_DEFAULT;
    magcal_ellipse_t e;
    magcal_cal2d_t cal;
    magcal_vec3_t m;
    float mag_deg = 0.0f;
    size_t i;
    magcal_status_t st = MAGCAL_OK;

    for (i = 0u; st == MAGCAL_OK && i < N_COLLECT; ++i) {
        st = magcal_port_mag_read(&m);
        g_pts[i].x = m.x;
        g_pts[i].y = m.y;
    }
    if (st == MAGCAL_OK) {
        st = magcal_optics_filter(&cfg, g_pts, N_COLLECT, g_work, sizeof g_work, g_inlier, NULL);
    }
    if (st == MAGCAL_OK) {
        st = magcal_ellipse_fit(g_pts, N_COLLECT, g_inlier, &e);
    }
    if (st == MAGCAL_OK) {
        st = magcal_ellipse_to_cal(&e, MAGCAL_CORR_SYMMETRIC, 0.0f, &cal);
    }
    if (st == MAGCAL_OK) {
        st = magcal_heading_compute(&cal, g_pts[3], 2.5f, &mag_deg, NULL);
    }
    g_heading_deg = mag_deg;
    g_status = (int)st;
    return st == MAGCAL_OK ? 0 : 1;
}
