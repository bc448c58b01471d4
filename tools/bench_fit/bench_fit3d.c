/* Deterministic driver for per-function instruction counts of the 3-D ellipsoid fit (issue 14):
 *   bench_fit3d fit|fit_ws|calibrate DUMP.csv
 * reads a recorded 3-D dump (header line, then mx,my,mz per row: the shared tumbles'
 * data.csv), runs magcal_ellipsoid_fit (or magcal_ellipsoid_calibrate with the default density
 * configuration; fit_ws: magcal_ellipsoid_fit_ws) once with the default configuration and prints the status, the model, the
 * calibration and the |B| spread (std / mean of |G (m - V)| over ALL samples), so the call is
 * not optimised away and the accuracy can be compared before / after a change. Count with
 *   LD_BIND_NOW=1 valgrind --tool=callgrind --toggle-collect=magcal_ellipsoid_fit \
 *       build/host/tools/bench_fit/bench_fit3d fit ../shared/data/real/fxos8700_tumble/data.csv
 * (README.md next to this file). Host tool: stdio, double for the report only. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "magcal/ellipsoid.h"

/* magcal_ellipsoid_fit's fixed scratch (the workspace-free fit: no per-sample storage) */
static magcal_ellipsoid_fit_scratch_t g_fit_scratch;

#define MAX_ROWS 4096u

static magcal_vec3_t g_m[MAX_ROWS];
static MAGCAL_ELLIPSOID_CALIBRATE_WORKSPACE_DECLARE(g_work, MAX_ROWS);

static size_t load(const char *path)
{
    char line[256];
    size_t n = 0u;
    FILE *f = fopen(path, "r");
    if (f == NULL) {
        return 0u;
    }
    while (n < MAX_ROWS && fgets(line, (int)sizeof line, f) != NULL) {
        float x;
        float y;
        float z;
        if (sscanf(line, "%f,%f,%f", &x, &y, &z) == 3) {
            g_m[n].x = x;
            g_m[n].y = y;
            g_m[n].z = z;
            ++n;
        }
    }
    (void)fclose(f);
    return n;
}

int main(int argc, char **argv)
{
    const magcal_ellipsoid_cfg_t cfg = MAGCAL_ELLIPSOID_CFG_DEFAULT;
    magcal_ellipsoid_calibrate_cfg_t ccfg = MAGCAL_ELLIPSOID_CALIBRATE_CFG_DEFAULT;
    magcal_ellipsoid_result_t r;
    magcal_status_t st;
    double s1 = 0.0;
    double s2 = 0.0;
    size_t n;
    size_t k;
    if (argc != 3 || (strcmp(argv[1], "fit") != 0 && strcmp(argv[1], "fit_ws") != 0 &&
                      strcmp(argv[1], "calibrate") != 0)) {
        (void)fprintf(stderr, "usage: bench_fit3d fit|fit_ws|calibrate DUMP.csv\n");
        return 2;
    }
    n = load(argv[2]);
    if (n == 0u) {
        (void)fprintf(stderr, "bench_fit3d: no samples in %s\n", argv[2]);
        return 2;
    }
    (void)memset(&r, 0, sizeof r);
    ccfg.fit = cfg;
    if (strcmp(argv[1], "fit") == 0) {
        st = magcal_ellipsoid_fit(g_m, n, &cfg, &g_fit_scratch, &r);
    } else if (strcmp(argv[1], "fit_ws") == 0) {
        st = magcal_ellipsoid_fit_ws(g_m, n, &cfg, g_work, sizeof g_work, &r);
    } else {
        st = magcal_ellipsoid_calibrate(&ccfg, g_m, n, g_work, sizeof g_work, NULL, &r, NULL);
    }
    if (st == MAGCAL_OK) {
        for (k = 0u; k < n; ++k) {
            magcal_vec3_t h;
            double b;
            (void)magcal_ellipsoid_apply(&r.cal, &g_m[k], &h);
            b = sqrt((double)h.x * h.x + (double)h.y * h.y + (double)h.z * h.z);
            s1 += b;
            s2 += b * b;
        }
        s1 /= (double)n;
        s2 = sqrt(s2 / (double)n - s1 * s1);
    }
    printf("%s n %u status %d model %d used %u F %.6g V (%.6g %.6g %.6g) rms %.6g "
           "snr %.4g centre_std %.5g shape_std %.5g spread %.5f\n",
           argv[1], (unsigned)n, (int)st, (int)r.model, (unsigned)r.n_used, (double)r.cal.field,
           (double)r.cal.v.x, (double)r.cal.v.y, (double)r.cal.v.z, (double)r.residual_rms,
           (double)r.motion_snr, (double)r.centre_std_rel, (double)r.shape_std,
           (st == MAGCAL_OK) ? s2 / s1 : -1.0);
    printf("G %.7g %.7g %.7g / %.7g %.7g %.7g / %.7g %.7g %.7g\n", (double)r.cal.g[0][0],
           (double)r.cal.g[0][1], (double)r.cal.g[0][2], (double)r.cal.g[1][0],
           (double)r.cal.g[1][1], (double)r.cal.g[1][2], (double)r.cal.g[2][0],
           (double)r.cal.g[2][1], (double)r.cal.g[2][2]);
    return (st == MAGCAL_OK) ? 0 : 1;
}
