/* Deterministic driver for instruction counts (valgrind --tool=callgrind --toggle-collect=FUNC).
 * Builds a 700-point distorted ring (raw-count scale, hard-iron offset 5x the radius), then calls
 * each measured function once and prints the results so nothing is optimised away. */
#include <math.h>
#include <stdio.h>

#include "magcal/ellipse.h"
#include "magcal/heading.h"

#define N_PTS 700u

static magcal_vec2_t pts[N_PTS];

int main(void)
{
    static const uint16_t idx5[5] = {0u, 140u, 280u, 420u, 560u};
    magcal_ellipse_t e;
    magcal_ellipse_t e5;
    magcal_cal2d_t cal;
    float mag = 0.0f;
    float tru = 0.0f;
    float res;
    magcal_status_t st;
    magcal_status_t st5;
    magcal_status_t sth;
    unsigned i;
    uint32_t rng = 12345u;

    for (i = 0u; i < N_PTS; ++i) {
        float psi = 6.2831853f * (float)i / (float)N_PTS;
        float hx = -1500.0f * sinf(psi);
        float hy = 1500.0f * cosf(psi);
        rng ^= rng << 13;
        rng ^= rng >> 17;
        rng ^= rng << 5;
        pts[i].x = 1.15f * hx + 0.2f * hy + 6000.0f + (float)(rng & 7u) - 3.5f;
        pts[i].y = 0.1f * hx + 0.85f * hy - 4500.0f + (float)((rng >> 3) & 7u) - 3.5f;
    }
    st = magcal_ellipse_fit(pts, N_PTS, NULL, &e);
    st5 = magcal_ellipse_fit_idx(pts, N_PTS, idx5, 5u, &e5);
    res = magcal_ellipse_residual(&e, pts[17]);
    (void)magcal_ellipse_to_cal(&e, MAGCAL_CORR_SYMMETRIC, 0.0f, &cal);
    sth = magcal_heading_compute(&cal, pts[100], 3.5f, &mag, &tru);
    printf("fit %d: centre (%.3f, %.3f) r1 %.3f r2 %.3f rms %.3f\n", (int)st, (double)e.center.x,
           (double)e.center.y, (double)e.semi_minor, (double)e.semi_major, (double)e.residual_rms);
    printf("fit5 %d: centre (%.3f, %.3f); residual %.4f; heading %d: %.3f / %.3f\n", (int)st5,
           (double)e5.center.x, (double)e5.center.y, (double)res, (int)sth, (double)mag,
           (double)tru);
    return (st == MAGCAL_OK && st5 == MAGCAL_OK && sth == MAGCAL_OK) ? 0 : 1;
}
