/*
 * magcal-geomag: expected Earth field from WMM2025 or IGRF-14 (include/magcal/geomag.h).
 *
 *   magcal-geomag LAT_DEG LON_DEG HEIGHT_KM DECIMAL_YEAR [--model wmm2025|igrf14]
 *
 * LAT_DEG: geodetic latitude, north +; LON_DEG: east +; HEIGHT_KM: above the WGS 84 ellipsoid;
 * DECIMAL_YEAR e.g. 2027.5. Prints one JSON object on stdout with exactly the names
 * declination_deg, inclination_deg, F_nT, H_nT, X_nT, Y_nT, Z_nT (X north, Y east, Z down).
 * Exit status: 0 ok, 1 evaluation refused (outside validity or range; message on stderr),
 * 2 usage error.
 */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "magcal/geomag.h"

static int usage(const char *msg)
{
    fprintf(stderr, "magcal-geomag: %s\n"
                    "usage: magcal-geomag LAT_DEG LON_DEG HEIGHT_KM DECIMAL_YEAR "
                    "[--model wmm2025|igrf14]\n",
            msg);
    return 2;
}

static int parse(const char *s, float *out)
{
    char *end = NULL;
    double v;
    errno = 0;
    v = strtod(s, &end);
    if (end == s || *end != '\0' || errno != 0) {
        return 0;
    }
    *out = (float)v;
    return 1;
}

int main(int argc, char **argv)
{
    const magcal_geomag_model_t *model = &magcal_geomag_wmm2025;
    float in[4];
    int npos = 0;
    int i;
    magcal_geomag_result_t r;
    magcal_status_t st;

    for (i = 1; i < argc; ++i) {
        if (strcmp(argv[i], "--model") == 0) {
            if (i + 1 >= argc) {
                return usage("--model needs a value");
            }
            ++i;
            if (strcmp(argv[i], "wmm2025") == 0) {
                model = &magcal_geomag_wmm2025;
            } else if (strcmp(argv[i], "igrf14") == 0) {
                model = &magcal_geomag_igrf14;
            } else {
                return usage("unknown model (wmm2025 or igrf14)");
            }
        } else if (npos < 4 && parse(argv[i], &in[npos])) {
            ++npos;
        } else {
            return usage("bad or extra argument");
        }
    }
    if (npos != 4) {
        return usage("four numbers needed");
    }
    st = magcal_geomag_eval(model, in[0], in[1], in[2], in[3], &r);
    if (st != MAGCAL_OK) {
        if (st == MAGCAL_ERR_OUT_OF_VALIDITY) {
            fprintf(stderr, "magcal-geomag: %s is valid from %.1f to %.1f only\n", model->name,
                    (double)model->valid_from, (double)model->valid_to);
        } else if (st == MAGCAL_ERR_ARG) {
            fprintf(stderr, "magcal-geomag: out of range (latitude -90..90, longitude -360..360, "
                            "height %.0f..%.0f km above the ellipsoid)\n",
                    (double)model->height_min_km, (double)model->height_max_km);
        }
        fprintf(stderr, "magcal-geomag: %s (%d)\n", magcal_status_str(st), (int)st);
        return 1;
    }
    printf("{\"declination_deg\": %.4f, \"inclination_deg\": %.4f, \"F_nT\": %.3f, "
           "\"H_nT\": %.3f, \"X_nT\": %.3f, \"Y_nT\": %.3f, \"Z_nT\": %.3f}\n",
           (double)r.decl_deg, (double)r.incl_deg, (double)r.f_nt, (double)r.h_nt,
           (double)r.x_nt, (double)r.y_nt, (double)r.z_nt);
    return 0;
}
