/*
 * Tests of the geomagnetic main-field module (include/magcal/geomag.h) against every official
 * test value of WMM2025 (report table, 100 high-precision points) and IGRF-14 (BGS points), and
 * against the double-precision evaluation written by tools/geomag/cof2c.py
 * (tests/support/geomag_testvalues.c, generated, with the official values).
 *
 * Tolerances (float32 library vs official values):
 *   report table (values rounded to 0.1 nT, 0.01 deg): X Y Z H F 0.08 nT, D I GV 0.007 deg,
 *     rates 0.06 nT/yr and 0.0055 deg/yr (official rounding 0.05 / 0.005 plus float32);
 *   high-precision points (values to 1e-6 nT, angles to 0.01 deg): components 0.03 nT,
 *     D I 0.0055 deg (rounding), rates 0.005 nT/yr;
 *   IGRF-14 BGS (values to 0.01 nT): X' Y' Z' 0.03 nT;
 *   against the double reference: components 0.03 nT, angles 0.0005 deg (measured maxima,
 *   about 0.02 nT and 1e-4 deg, are printed; see docs/geomag.md).
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "geomag_testvalues.h"
#include "magcal/geomag.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

/* Largest |float32 - truth| per quantity over a table, for the printed report. */
typedef struct {
    double comp;  /* X Y Z H F (nT) */
    double ang;   /* D I GV (deg) */
    double rate;  /* Xdot..Fdot (nT/yr) */
    double arate; /* Ddot Idot (deg/yr) */
} max_err_t;

static double wrap180(double a)
{
    a = fmod(a, 360.0);
    if (a > 180.0) {
        a -= 360.0;
    } else if (a <= -180.0) {
        a += 360.0;
    }
    return a;
}

static void upd(double *m, double e)
{
    e = fabs(e);
    if (e > *m) {
        *m = e;
    }
}

/* Compare r with either the official values (use_ref = 0) or the double reference (1). */
static void compare(const geomag_tv_t *tv, const magcal_geomag_result_t *r, int use_ref,
                    max_err_t *me)
{
    const double off[15] = {tv->x,    tv->y,    tv->z,    tv->h,    tv->f,
                            tv->decl, tv->incl, tv->gv,   tv->xdot, tv->ydot,
                            tv->zdot, tv->hdot, tv->fdot, tv->ddot, tv->idot};
    const double ref[15] = {tv->rx,    tv->ry,    tv->rz,    tv->rh,    tv->rf,
                            tv->rdecl, tv->rincl, tv->rgv,   tv->rxdot, tv->rydot,
                            tv->rzdot, tv->rhdot, tv->rfdot, tv->rddot, tv->ridot};
    const double got[15] = {r->x_nt,        r->y_nt,        r->z_nt,          r->h_nt,
                            r->f_nt,        r->decl_deg,    r->incl_deg,      r->grid_var_deg,
                            r->x_dot_nt_yr, r->y_dot_nt_yr, r->z_dot_nt_yr,   r->h_dot_nt_yr,
                            r->f_dot_nt_yr, r->decl_dot_deg_yr, r->incl_dot_deg_yr};
    const double *t = use_ref ? ref : off;
    int i;
    for (i = 0; i < 15; ++i) {
        double e;
        if (isnan(t[i])) {
            continue; /* no grid variation outside the polar regions */
        }
        e = got[i] - t[i];
        if (i >= 5 && i <= 7) {
            e = wrap180(e);
        }
        if (i < 5) {
            upd(&me->comp, e);
        } else if (i < 8) {
            upd(&me->ang, e);
        } else if (i < 13) {
            upd(&me->rate, e);
        } else {
            upd(&me->arate, e);
        }
    }
}

static void run_table(const geomag_tv_t *tab, size_t n, const magcal_geomag_model_t *model,
                      max_err_t *vs_off, max_err_t *vs_ref)
{
    size_t i;
    memset(vs_off, 0, sizeof *vs_off);
    memset(vs_ref, 0, sizeof *vs_ref);
    for (i = 0; i < n; ++i) {
        magcal_geomag_result_t r;
        const magcal_geomag_model_t *m = model;
        if (m == NULL) {
            m = (tab[i].model == 0) ? &magcal_geomag_wmm2025 : &magcal_geomag_igrf14;
        }
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK,
                              magcal_geomag_eval(m, (float)tab[i].lat_deg, (float)tab[i].lon_deg,
                                                 (float)tab[i].height_km, (float)tab[i].year, &r));
        compare(&tab[i], &r, 0, vs_off);
        compare(&tab[i], &r, 1, vs_ref);
    }
}

static void print_err(const char *what, const max_err_t *e)
{
    printf("  %-34s max |err|: XYZHF %.4f nT  D/I/GV %.5f deg  rates %.4f nT/yr  %.5f deg/yr\n",
           what, e->comp, e->ang, e->rate, e->arate);
}

static void test_eval_wmm_report_table_matches_official(void)
{
    max_err_t off;
    max_err_t ref;
    run_table(geomag_tv_wmm_report, GEOMAG_TV_WMM_REPORT_N, &magcal_geomag_wmm2025, &off, &ref);
    print_err("WMM2025 report table vs official", &off);
    print_err("WMM2025 report table vs double ref", &ref);
    TEST_ASSERT_DOUBLE_WITHIN(0.08, 0.0, off.comp);
    TEST_ASSERT_DOUBLE_WITHIN(0.007, 0.0, off.ang);
    TEST_ASSERT_DOUBLE_WITHIN(0.06, 0.0, off.rate);
    TEST_ASSERT_DOUBLE_WITHIN(0.0055, 0.0, off.arate);
    TEST_ASSERT_DOUBLE_WITHIN(0.03, 0.0, ref.comp);
    TEST_ASSERT_DOUBLE_WITHIN(0.0005, 0.0, ref.ang);
}

static void test_eval_wmm_highprec_points_match_official(void)
{
    max_err_t off;
    max_err_t ref;
    run_table(geomag_tv_wmm_highprec, GEOMAG_TV_WMM_HIGHPREC_N, &magcal_geomag_wmm2025, &off,
              &ref);
    print_err("WMM2025 100 high-prec vs official", &off);
    print_err("WMM2025 100 high-prec vs double ref", &ref);
    TEST_ASSERT_DOUBLE_WITHIN(0.03, 0.0, off.comp);
    TEST_ASSERT_DOUBLE_WITHIN(0.0055, 0.0, off.ang);
    TEST_ASSERT_DOUBLE_WITHIN(0.005, 0.0, off.rate);
    TEST_ASSERT_DOUBLE_WITHIN(0.03, 0.0, ref.comp);
    TEST_ASSERT_DOUBLE_WITHIN(0.0005, 0.0, ref.ang);
}

static void test_eval_extra_points_match_double_reference(void)
{
    /* poles (both frames), height and date limits, IGRF degree-10/13 epochs and SV */
    max_err_t off;
    max_err_t ref;
    run_table(geomag_tv_extra, GEOMAG_TV_EXTRA_N, NULL, &off, &ref);
    print_err("extra points vs double ref", &ref);
    TEST_ASSERT_DOUBLE_WITHIN(0.03, 0.0, ref.comp);
    TEST_ASSERT_DOUBLE_WITHIN(0.0005, 0.0, ref.ang);
    TEST_ASSERT_DOUBLE_WITHIN(0.005, 0.0, ref.rate);
}

static void test_eval_geocentric_igrf_bgs_points_match_official(void)
{
    double e_off = 0.0;
    double e_ref = 0.0;
    size_t i;
    for (i = 0; i < GEOMAG_TV_IGRF_BGS_N; ++i) {
        const geomag_tv_gc_t *tv = &geomag_tv_igrf_bgs[i];
        float b[3];
        float bd[3];
        int k;
        const double off[3] = {tv->x, tv->y, tv->z};
        const double ref[3] = {tv->rx, tv->ry, tv->rz};
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_geomag_eval_geocentric(
                                             &magcal_geomag_igrf14, (float)(90.0 - tv->colat_deg),
                                             (float)tv->lon_deg, (float)tv->radius_km,
                                             (float)tv->year, b, bd));
        for (k = 0; k < 3; ++k) {
            upd(&e_off, b[k] - off[k]);
            upd(&e_ref, b[k] - ref[k]);
        }
    }
    printf("  IGRF-14 BGS (12) X'Y'Z' max |err|: vs official %.4f nT, vs double ref %.4f nT\n",
           e_off, e_ref);
    TEST_ASSERT_DOUBLE_WITHIN(0.03, 0.0, e_off);
    TEST_ASSERT_DOUBLE_WITHIN(0.03, 0.0, e_ref);
}

static void test_eval_pole_is_continuous_with_nearby_latitude(void)
{
    /* 0.0001 deg (11 m) from the pole in the same meridian frame: the field barely changes. */
    magcal_geomag_result_t p;
    magcal_geomag_result_t q;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK,
                          magcal_geomag_eval(&magcal_geomag_wmm2025, 90.0f, 30.0f, 0.0f, 2026.0f, &p));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_geomag_eval(&magcal_geomag_wmm2025, 89.9999f, 30.0f,
                                                        0.0f, 2026.0f, &q));
    TEST_ASSERT_FLOAT_WITHIN(0.5f, q.x_nt, p.x_nt);
    TEST_ASSERT_FLOAT_WITHIN(0.5f, q.y_nt, p.y_nt);
    TEST_ASSERT_FLOAT_WITHIN(0.5f, q.z_nt, p.z_nt);
    TEST_ASSERT_FLOAT_WITHIN(0.01f, q.grid_var_deg, p.grid_var_deg);
    TEST_ASSERT_EQUAL_UINT8(1u, p.polar);
}

static void test_eval_zone_follows_horizontal_intensity(void)
{
    /* The high-precision set has points in the blackout (H 1504 nT) and caution zones. */
    size_t i;
    int seen[3] = {0, 0, 0};
    for (i = 0; i < GEOMAG_TV_WMM_HIGHPREC_N; ++i) {
        const geomag_tv_t *tv = &geomag_tv_wmm_highprec[i];
        magcal_geomag_result_t r;
        magcal_geomag_zone_t want = MAGCAL_GEOMAG_ZONE_NORMAL;
        if (fabs(tv->h - 2000.0) < 1.0 || fabs(tv->h - 6000.0) < 1.0) {
            continue;
        }
        if (tv->h < 2000.0) {
            want = MAGCAL_GEOMAG_ZONE_BLACKOUT;
        } else if (tv->h < 6000.0) {
            want = MAGCAL_GEOMAG_ZONE_CAUTION;
        }
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_geomag_eval(&magcal_geomag_wmm2025,
                                                            (float)tv->lat_deg, (float)tv->lon_deg,
                                                            (float)tv->height_km, (float)tv->year,
                                                            &r));
        TEST_ASSERT_EQUAL_INT(want, r.zone);
        TEST_ASSERT_EQUAL_UINT8(fabs(tv->lat_deg) > 55.0 ? 1u : 0u, r.polar);
        seen[want] = 1;
    }
    TEST_ASSERT_EQUAL_INT(1, seen[MAGCAL_GEOMAG_ZONE_BLACKOUT]);
    TEST_ASSERT_EQUAL_INT(1, seen[MAGCAL_GEOMAG_ZONE_CAUTION]);
    TEST_ASSERT_EQUAL_INT(1, seen[MAGCAL_GEOMAG_ZONE_NORMAL]);
}

static void test_eval_igrf_is_continuous_across_epochs(void)
{
    /* Linear interpolation is continuous at each epoch, including the degree-10/13 change at
     * 2000 and the switch to the SV at 2025: 1e-3 yr apart the field moves < 0.3 nT. */
    static const float epochs[4] = {1950.0f, 2000.0f, 2020.0f, 2025.0f};
    int i;
    for (i = 0; i < 4; ++i) {
        magcal_geomag_result_t a;
        magcal_geomag_result_t b;
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_geomag_eval(&magcal_geomag_igrf14, 40.0f, -75.0f,
                                                            0.0f, epochs[i] - 0.001f, &a));
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_geomag_eval(&magcal_geomag_igrf14, 40.0f, -75.0f,
                                                            0.0f, epochs[i], &b));
        TEST_ASSERT_FLOAT_WITHIN(0.3f, a.x_nt, b.x_nt);
        TEST_ASSERT_FLOAT_WITHIN(0.3f, a.y_nt, b.y_nt);
        TEST_ASSERT_FLOAT_WITHIN(0.3f, a.z_nt, b.z_nt);
    }
}

static void test_eval_outside_validity_returns_out_of_validity(void)
{
    magcal_geomag_result_t r;
    magcal_geomag_result_t keep;
    float b[3] = {1.0f, 2.0f, 3.0f};
    memset(&r, 0x5a, sizeof r);
    keep = r;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_OUT_OF_VALIDITY,
                          magcal_geomag_eval(&magcal_geomag_wmm2025, 0.0f, 0.0f, 0.0f, 2024.999f, &r));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_OUT_OF_VALIDITY,
                          magcal_geomag_eval(&magcal_geomag_wmm2025, 0.0f, 0.0f, 0.0f, 2030.001f, &r));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_OUT_OF_VALIDITY,
                          magcal_geomag_eval(&magcal_geomag_igrf14, 0.0f, 0.0f, 0.0f, 1899.99f, &r));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_OUT_OF_VALIDITY,
                          magcal_geomag_eval(&magcal_geomag_igrf14, 0.0f, 0.0f, 0.0f, 2030.01f, &r));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_OUT_OF_VALIDITY,
                          magcal_geomag_eval_geocentric(&magcal_geomag_igrf14, 0.0f, 0.0f, 6371.2f,
                                                        2031.0f, b, NULL));
    TEST_ASSERT_EQUAL_MEMORY(&keep, &r, sizeof r);
    TEST_ASSERT_EQUAL_FLOAT(1.0f, b[0]);
    /* the end points are valid */
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK,
                          magcal_geomag_eval(&magcal_geomag_wmm2025, 0.0f, 0.0f, 0.0f, 2025.0f, &r));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK,
                          magcal_geomag_eval(&magcal_geomag_wmm2025, 0.0f, 0.0f, 0.0f, 2030.0f, &r));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK,
                          magcal_geomag_eval(&magcal_geomag_igrf14, 0.0f, 0.0f, 0.0f, 1900.0f, &r));
}

static void test_eval_bad_input_returns_status(void)
{
    const magcal_geomag_model_t *w = &magcal_geomag_wmm2025;
    magcal_geomag_model_t bad = magcal_geomag_wmm2025;
    magcal_geomag_result_t r;
    float b[3];
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_geomag_eval(NULL, 0.0f, 0.0f, 0.0f, 2026.0f, &r));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_geomag_eval(w, 0.0f, 0.0f, 0.0f, 2026.0f, NULL));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE, magcal_geomag_eval(w, NAN, 0.0f, 0.0f, 2026.0f, &r));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE, magcal_geomag_eval(w, 0.0f, INFINITY, 0.0f, 2026.0f, &r));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE, magcal_geomag_eval(w, 0.0f, 0.0f, NAN, 2026.0f, &r));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE, magcal_geomag_eval(w, 0.0f, 0.0f, 0.0f, NAN, &r));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_geomag_eval(w, 90.01f, 0.0f, 0.0f, 2026.0f, &r));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_geomag_eval(w, -90.01f, 0.0f, 0.0f, 2026.0f, &r));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_geomag_eval(w, 0.0f, 360.5f, 0.0f, 2026.0f, &r));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_geomag_eval(w, 0.0f, 0.0f, -1.01f, 2026.0f, &r));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_geomag_eval(w, 0.0f, 0.0f, 850.1f, 2026.0f, &r));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_geomag_eval_geocentric(w, 0.0f, 0.0f, 5999.0f,
                                                                      2026.0f, b, NULL));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_geomag_eval_geocentric(w, 91.0f, 0.0f, 6371.0f,
                                                                      2026.0f, b, NULL));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_geomag_eval_geocentric(w, 0.0f, 0.0f, 6371.0f,
                                                                       2026.0f, NULL, NULL));
    bad.nmax = (uint8_t)(MAGCAL_GEOMAG_NMAX + 1u);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_geomag_eval(&bad, 0.0f, 0.0f, 0.0f, 2026.0f, &r));
}

static void test_decimal_year_known_dates_and_invalid(void)
{
    float y = 0.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_geomag_decimal_year(2025, 1, 1, &y));
    TEST_ASSERT_EQUAL_FLOAT(2025.0f, y);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_geomag_decimal_year(2025, 7, 2, &y));
    TEST_ASSERT_FLOAT_WITHIN(1e-4f, 2025.0f + 182.0f / 365.0f, y); /* day-of-year 183 */
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_geomag_decimal_year(2028, 12, 31, &y));
    TEST_ASSERT_FLOAT_WITHIN(1e-4f, 2028.0f + 365.0f / 366.0f, y); /* leap year */
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_geomag_decimal_year(2000, 2, 29, &y));
    y = 1.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_geomag_decimal_year(2025, 2, 29, &y));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_geomag_decimal_year(1900, 2, 29, &y));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_geomag_decimal_year(2025, 13, 1, &y));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_geomag_decimal_year(2025, 4, 31, &y));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_geomag_decimal_year(2025, 1, 0, &y));
    TEST_ASSERT_EQUAL_FLOAT(1.0f, y);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_geomag_decimal_year(2025, 1, 1, NULL));
}

static void test_models_descriptors_match_official_files(void)
{
    /* Spot values straight from WMM.COF and igrf14coeffs.txt. */
    const magcal_geomag_model_t *w = &magcal_geomag_wmm2025;
    const magcal_geomag_model_t *g = &magcal_geomag_igrf14;
    TEST_ASSERT_EQUAL_UINT8(12u, w->nmax);
    TEST_ASSERT_EQUAL_UINT8(1u, w->n_epochs);
    TEST_ASSERT_EQUAL_FLOAT(-29351.8f, w->coef[0]);     /* g_1^0 */
    TEST_ASSERT_EQUAL_FLOAT(4545.4f, w->coef[2]);       /* h_1^1 */
    TEST_ASSERT_EQUAL_FLOAT(-21.5f, w->sv[2]);          /* hdot_1^1 */
    TEST_ASSERT_EQUAL_FLOAT(0.2f, w->coef[MAGCAL_GEOMAG_NCOEF(12u) - 1u]); /* h_12^12 */
    TEST_ASSERT_EQUAL_UINT8(13u, g->nmax);
    TEST_ASSERT_EQUAL_UINT8(26u, g->n_epochs);
    TEST_ASSERT_EQUAL_UINT8(8u, g->sv_nmax);
    TEST_ASSERT_EQUAL_UINT8(10u, g->epoch_nmax[0]);
    TEST_ASSERT_EQUAL_UINT8(13u, g->epoch_nmax[20]); /* 2000.0 */
    TEST_ASSERT_EQUAL_FLOAT(-31543.0f, g->coef[g->epoch_start[0]]);
    TEST_ASSERT_EQUAL_FLOAT(-0.9f, g->coef[g->epoch_start[20] + MAGCAL_GEOMAG_NCOEF(13u) - 1u]);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_eval_wmm_report_table_matches_official);
    RUN_TEST(test_eval_wmm_highprec_points_match_official);
    RUN_TEST(test_eval_extra_points_match_double_reference);
    RUN_TEST(test_eval_geocentric_igrf_bgs_points_match_official);
    RUN_TEST(test_eval_pole_is_continuous_with_nearby_latitude);
    RUN_TEST(test_eval_zone_follows_horizontal_intensity);
    RUN_TEST(test_eval_igrf_is_continuous_across_epochs);
    RUN_TEST(test_eval_outside_validity_returns_out_of_validity);
    RUN_TEST(test_eval_bad_input_returns_status);
    RUN_TEST(test_decimal_year_known_dates_and_invalid);
    RUN_TEST(test_models_descriptors_match_official_files);
    return UNITY_END();
}
