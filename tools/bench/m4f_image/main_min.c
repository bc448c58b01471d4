/* Footprint image of the minimal 2-D firmware of issue 14 (`m4f_flash_min_bytes`): samples through
 * the port, the improved-OPTICS density filter (automatic parameters), the consensus stage on its
 * inliers, the least-squares ellipse of the consensus set, correction and one heading: what a
 * firmware links when it calibrates in one call without the calibrator object, DBSCAN, 3-D or
 * geomag. Capacity = MAGCAL_MAX_SAMPLES (1024). */
#include <stdint.h>

#include "magcal/consensus.h"
#include "magcal/ellipse.h"
#include "magcal/heading.h"
#include "magcal/optics.h"
#include "magcal_port.h"

#define CAP ((size_t)MAGCAL_MAX_SAMPLES)
#define N_COLLECT 48u
#define WORK_LEN                                                                                   \
    ((MAGCAL_OPTICS_FILTER_WORKSPACE_LEN(CAP) > MAGCAL_CONSENSUS_WORKSPACE_LEN(CAP))                \
         ? MAGCAL_OPTICS_FILTER_WORKSPACE_LEN(CAP)                                                  \
         : MAGCAL_CONSENSUS_WORKSPACE_LEN(CAP))

static magcal_vec2_t g_pts[CAP];
static uint8_t g_cand[CAP];
static uint8_t g_inlier[CAP];
static uint32_t g_work[(WORK_LEN + 3u) / 4u];

volatile float g_heading_deg;
volatile int g_status;

int main(void)
{
    magcal_optics_cfg_t cfg = MAGCAL_OPTICS_CFG_DEFAULT; /* IMPROVED + GRID, automatic eps */
    const magcal_consensus_cfg_t ccfg = MAGCAL_CONSENSUS_CFG_DEFAULT;
    magcal_consensus_result_t cres;
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
        st = magcal_optics_filter(&cfg, g_pts, N_COLLECT, g_work, sizeof g_work, g_cand, NULL);
    }
    if (st == MAGCAL_OK) {
        st = magcal_consensus_run(&ccfg, g_pts, N_COLLECT, g_cand, g_work, sizeof g_work, g_inlier, &cres);
    }
    if (st == MAGCAL_OK) {
        st = magcal_ellipse_to_cal(&cres.fit, MAGCAL_CORR_SYMMETRIC, 0.0f, &cal);
    }
    if (st == MAGCAL_OK) {
        st = magcal_heading_compute(&cal, g_pts[3], 2.5f, &mag_deg, NULL);
    }
    g_heading_deg = mag_deg;
    g_status = (int)st;
    return st == MAGCAL_OK ? 0 : 1;
}
