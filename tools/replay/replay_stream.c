/*
 * magcal-replay --stream [--mode 2d|3d] [--headings OUT.csv] [--json] [--declination DEG] DUMP.csv
 * Feeds every row (no limit, no decimation) through magcal_cont_push + magcal_cont_step at the
 * default configuration, then magcal_cont_heading for the row (--mode 3d: the continuous 3-D
 * calibrator, magcal_cont3_*, tilt compensated when the dump has ax, ay, az). Headings CSV:
 * index,raw_heading_deg,heading_deg,trust,generation[,heading_ref_deg,error_deg]. JSON: the
 * calibration in force at the end (the batch report's fields), "events", "rows", "trusted_rows".
 */
#include "replay_stream.h"

#include <cjson/cJSON.h>
#include <getopt.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "magcal/continuous.h"
#include "magcal/continuous3.h"
#include "magcal/record.h"
#include "replay_record.h"
#include "replay_csv.h"

#define RS_SECTORS 36u
#define RS_PER_BIN 8u
#define RS_SLOTS MAGCAL_CONT_SLOTS(RS_SECTORS, RS_PER_BIN)

static magcal_intake_slot_t g_slots[RS_SLOTS];
static magcal_vec2_t g_buf[RS_SLOTS];
static MAGCAL_CALIBRATOR_WORKSPACE_DECLARE(g_work, RS_SLOTS);
static magcal_cont_t g_cc;

#define RS3_SLOTS MAGCAL_CONT3_SLOTS(10u, 4u)
static magcal_intake_slot_t g_slots3[RS3_SLOTS];
static magcal_vec3_t g_buf3[RS3_SLOTS];
static MAGCAL_CONT3_WORKSPACE_DECLARE(g_work3, RS3_SLOTS);
static magcal_cont3_t g_c3;

static const char k_stream_usage[] =
    "usage: magcal-replay --stream [--mode 2d|3d] [--headings OUT.csv] [--json] [--declination DEG]\n"
    "                        [--range R] [--steps-per-row K] [--coarse DEG[,TOL]] [--arc DEG[,TOL[,MODEL]]]\n"
    "                        [--continuity 0|1] [--no-tilt] [--level-tilt DEG] [--install REC] [--save REC]\n"
    "                        [--no-gyro] [--gyro-unit rads|dps] [--gyro-gravity] [--ok-max-err DEG] DUMP.csv\n"
    "                        (R: the sensor's declared range)\n"
    "  --coarse: 2-D coarse stage on (cfg.coarse_coverage_deg DEG, cfg.coarse_max_err_deg TOL; off by\n"
    "  default): adoptions of a hard-iron circle carry status \"coarse\", its headings trust \"coarse\";\n"
    "  --arc DEG[,TOL[,MODEL]]: 2-D arc stage on (cfg.arc_coverage_deg, arc_max_err_deg,\n"
    "  arc_model_deg; off by default, continuous.h \"Arc calibration\"): an ellipse fitted on an arc\n"
    "  below 270 deg is installed as a coarse one when its whole-circle bound holds;\n"
    "  --continuity 0|1: cfg.continuity (the drain's continuity gate, continuous.h);\n"
    "  every row in file order through magcal_cont_push + K x magcal_cont_step (default budget; K = 1:\n"
    "  a control loop at the sample rate) and magcal_cont_heading; after the last row, steps without\n"
    "  pushes until the solve under way ends (events at row = rows);\n"
    "  --headings: index,raw_heading_deg,heading_deg,trust,generation\n"
    "  [,heading_ref_deg,error_deg]; --json: calibration in force at the end, events, rows, trusted_rows\n"
    "  --mode 3d: magcal_cont3_* (3-D store, ellipsoid solve), tilt-compensated headings when the\n"
    "  dump has ax, ay, az in g, mg or m/s^2 (else the level formula)\n"
    "  2-D gravity feed: when the dump has ax, ay, az in g, mg or m/s^2 (unit detected from the median\n"
    "  |a|), each row is pushed with magcal_cont_push_g (the store prefers level samples; JSON\n"
    "  \"gravity_fed\": true), else with magcal_cont_push; --no-tilt: never (magcal_cont_push, as\n"
    "  without an accelerometer); --level-tilt DEG: cfg.intake.tilt_limit_deg (default 2; 0 = off)\n"
    "  --install REC: start from the 2-D flash record REC (magcal/record.h; a calibration restored at\n"
    "  power-up); --save REC: write the full calibration in force at the end as such a record\n"
    "  gyro: when the dump has gx, gy, gz (--gyro-unit rads (default) | dps), each row is pushed with\n"
    "  magcal_cont_push_imu (the gyro heading check, continuous.h; JSON \"gyro_fed\": true, rate_flags,\n"
    "  rate_sign, rate_bias_dps, gravity_locked, gravity_unlocks); --no-gyro: never;\n"
    "  --gyro-gravity: cfg.gyro_gravity 1 (with the gyro, push_g levels with the gyro-carried gravity\n"
    "  where the accelerometer reads the vehicle's acceleration; continuous.h \"Gyro-aided gravity\")\n"
    "  --ok-max-err DEG: cfg.ok_max_err_deg (default 3; 0 = off): a full calibration whose error\n"
    "  estimate is above it gives COARSE headings (continuous.h \"OK tolerance\")\n";

/* Open the headings CSV (hpath NULL: none) and write its header; 0 when it cannot be written
 * (said on stderr). */
static int stream_headings_open(const char *hpath, int with_ref, FILE **hf)
{
    *hf = NULL;
    if (hpath == NULL) {
        return 1;
    }
    *hf = fopen(hpath, "w");
    if (*hf == NULL) {
        fprintf(stderr, "magcal-replay: cannot write %s\n", hpath);
        return 0;
    }
    fprintf(*hf, "index,raw_heading_deg,heading_deg,trust,generation%s\n",
            with_ref ? ",heading_ref_deg,error_deg" : "");
    return 1;
}

/* The push stamp of row i: ms since the first row's t, or 50 Hz rows without a time column. */
static uint32_t stream_row_ms(const double *tc, size_t i)
{
    if (tc != NULL && isfinite(tc[i]) && isfinite(tc[0])) {
        return (uint32_t)(int64_t)llround((tc[i] - tc[0]) * 1000.0);
    }
    return (uint32_t)(i * 20u); /* no time column: 50 Hz */
}

int replay_stream_requested(int argc, char **argv)
{
    int i;
    for (i = 1; i < argc; ++i) {
        if (strcmp(argv[i], "--stream") == 0) {
            return 1;
        }
        if (strcmp(argv[i], "--") == 0) {
            break;
        }
    }
    return 0;
}

static double wrap180(double a)
{
    a = fmod(a + 180.0, 360.0);
    if (a < 0.0) {
        a += 360.0;
    }
    return a - 180.0;
}

static void add_event(cJSON *ev, size_t row, const char *what, const char *status, double err)
{
    cJSON *e = cJSON_CreateObject();
    cJSON_AddNumberToObject(e, "row", (double)row);
    cJSON_AddStringToObject(e, "event", what);
    cJSON_AddStringToObject(e, "status", status);
    if (isfinite(err)) {
        cJSON_AddNumberToObject(e, "heading_err_deg", err);
    } else {
        cJSON_AddNullToObject(e, "heading_err_deg");
    }
    cJSON_AddItemToArray(ev, e);
}

/* The report's fields both modes share, after their own: loop counters, the trusted rows' RMS
 * against the dump's reference (when it has one), and the events (the report takes ev over). */
#define TAIL_IDLE 256u /* IDLE steps in a row that end the tail */

static void stream_report_tail(cJSON *root, uint32_t solves, uint32_t changes, uint32_t dropped, double ref_ss,
                               size_t ref_n, cJSON *ev)
{
    cJSON_AddNumberToObject(root, "solves", (double)solves);
    cJSON_AddNumberToObject(root, "changes", (double)changes);
    cJSON_AddNumberToObject(root, "dropped", (double)dropped);
    if (ref_n > 0u) {
        cJSON_AddNumberToObject(root, "heading_rms_trusted_deg", sqrt(ref_ss / (double)ref_n));
    }
    cJSON_AddItemToObject(root, "events", ev);
}

static void stream_print_json(const cJSON *root)
{
    char *s = cJSON_Print(root);
    if (s != NULL) {
        puts(s);
        free(s);
    }
}

static void add_cal(cJSON *o, const magcal_cont_t *cc)
{
    const magcal_cal_report_t *r = &cc->last;
    cJSON *off = cJSON_CreateArray();
    cJSON *m = cJSON_CreateArray();
    int i;
    cJSON_AddItemToArray(off, cJSON_CreateNumber((double)cc->cal.offset.x));
    cJSON_AddItemToArray(off, cJSON_CreateNumber((double)cc->cal.offset.y));
    for (i = 0; i < 2; ++i) {
        cJSON *row = cJSON_CreateArray();
        cJSON_AddItemToArray(row, cJSON_CreateNumber((double)cc->cal.m[i][0]));
        cJSON_AddItemToArray(row, cJSON_CreateNumber((double)cc->cal.m[i][1]));
        cJSON_AddItemToArray(m, row);
    }
    cJSON_AddStringToObject(o, "status", cc->generation > 0u ? "ok" : magcal_status_str(cc->last_status));
    cJSON_AddNumberToObject(o, "status_code", cc->generation > 0u ? 0.0 : (double)cc->last_status);
    cJSON_AddStringToObject(o, "mode", "2d");
    cJSON_AddItemToObject(o, "offset", off);
    cJSON_AddItemToObject(o, "matrix", m);
    cJSON_AddNumberToObject(o, "radius", (double)cc->cal.radius);
    cJSON_AddNumberToObject(o, "generation", (double)cc->generation);
    cJSON_AddBoolToObject(o, "coarse", cc->cal_coarse != 0u);
    /* the report of the last finished solve (the one in force when generation > 0 and it adopted) */
    cJSON_AddStringToObject(o, "last_solve_status", magcal_status_str(r->status));
    cJSON_AddNumberToObject(o, "n_used", (double)r->used);
    cJSON_AddNumberToObject(o, "n_outliers", (double)r->outliers);
    cJSON_AddNumberToObject(o, "coverage_deg", (double)r->coverage_deg);
    if (isfinite(cc->adopted_err)) {
        cJSON_AddNumberToObject(o, "est_heading_err_deg", (double)cc->adopted_err);
    } else {
        cJSON_AddNullToObject(o, "est_heading_err_deg");
    }
}

/* ---- --mode 3d: the continuous 3-D calibrator (magcal_cont3_*) ---- */

static int cmp_double(const void *a, const void *b)
{
    const double x = *(const double *)a;
    const double y = *(const double *)b;
    return (x > y) - (x < y);
}

/* Scale of the dump's accelerometer to g from its median |a| (g, mg, m/s^2 as the batch mode
 * detects them); 0 when there is no accelerometer or its unit cannot be told (raw counts). */
static double stream3_accel_scale(const magcal_replay_csv_t *d)
{
    double *nrm;
    size_t i, k = 0u;
    double med, scale = 0.0;
    if (d->col[MAGCAL_REPLAY_COL_AX] == NULL || d->col[MAGCAL_REPLAY_COL_AY] == NULL ||
        d->col[MAGCAL_REPLAY_COL_AZ] == NULL || d->n_rows == 0u) {
        return 0.0;
    }
    nrm = (double *)malloc(d->n_rows * sizeof *nrm);
    if (nrm == NULL) {
        return 0.0;
    }
    for (i = 0u; i < d->n_rows; ++i) {
        const double ax = d->col[MAGCAL_REPLAY_COL_AX][i], ay = d->col[MAGCAL_REPLAY_COL_AY][i],
                     az = d->col[MAGCAL_REPLAY_COL_AZ][i];
        if (isfinite(ax) && isfinite(ay) && isfinite(az)) {
            nrm[k++] = sqrt(ax * ax + ay * ay + az * az);
        }
    }
    if (k > 0u) {
        qsort(nrm, k, sizeof *nrm, cmp_double);
        med = nrm[k / 2u];
        scale = (med >= 0.5 && med <= 2.0)      ? 1.0
                : (med >= 4.9 && med <= 19.6)   ? 1.0 / 9.80665
                : (med >= 500.0 && med <= 2000.0) ? 1e-3
                                                  : 0.0;
    }
    free(nrm);
    return scale;
}

/* |B| spread (std / mean of |G (m - V)|) of the calibration in force over every finite row. */
static double stream3_spread(const magcal_replay_csv_t *d, const magcal_ellipsoid_cal_t *cal)
{
    double s = 0.0, s2 = 0.0;
    size_t i, k = 0u;
    for (i = 0u; i < d->n_rows; ++i) {
        magcal_vec3_t m, h;
        m.x = (float)d->col[MAGCAL_REPLAY_COL_MX][i];
        m.y = (float)d->col[MAGCAL_REPLAY_COL_MY][i];
        m.z = (float)d->col[MAGCAL_REPLAY_COL_MZ][i];
        if (magcal_ellipsoid_apply(cal, &m, &h) == MAGCAL_OK) {
            const double r = sqrt((double)h.x * h.x + (double)h.y * h.y + (double)h.z * h.z);
            s += r;
            s2 += r * r;
            k++;
        }
    }
    if (k < 2u || s <= 0.0) {
        return NAN;
    }
    return sqrt(fmax(s2 / (double)k - (s / (double)k) * (s / (double)k), 0.0)) / (s / (double)k);
}

/* Estimated heading error (deg, 1 sigma) of a 3-D fit, as the 2-D estimate (calibrator.h
 * "Heading-error estimates": sqrt(noise^2 + parameters^2)) from the fit's own diagnostics: the
 * per-sample noise residual_rms / F and the predicted errors of V (centre_std_rel, its worst
 * direction) and of G (shape_std), taken at a horizontal field of F (a real one of F cos(incl)
 * scales it by 1 / cos(incl)); NaN when not finite. */
static double stream3_est_err(const magcal_ellipsoid_result_t *r)
{
    const double nz = (double)r->residual_rms / (double)r->cal.field;
    const double c = (double)r->centre_std_rel;
    const double g = (double)r->shape_std;
    const double e = (180.0 / 3.14159265358979) * sqrt(nz * nz + c * c + g * g);
    return isfinite(e) ? e : NAN;
}

static void add_cal3(cJSON *o, const magcal_cont3_t *c3, const magcal_replay_csv_t *d)
{
    const magcal_ellipsoid_result_t *r = &c3->last;
    cJSON *off = cJSON_CreateArray();
    cJSON *m = cJSON_CreateArray();
    int i;
    cJSON_AddItemToArray(off, cJSON_CreateNumber((double)c3->cal.v.x));
    cJSON_AddItemToArray(off, cJSON_CreateNumber((double)c3->cal.v.y));
    cJSON_AddItemToArray(off, cJSON_CreateNumber((double)c3->cal.v.z));
    for (i = 0; i < 3; ++i) {
        cJSON *row = cJSON_CreateArray();
        cJSON_AddItemToArray(row, cJSON_CreateNumber((double)c3->cal.g[i][0]));
        cJSON_AddItemToArray(row, cJSON_CreateNumber((double)c3->cal.g[i][1]));
        cJSON_AddItemToArray(row, cJSON_CreateNumber((double)c3->cal.g[i][2]));
        cJSON_AddItemToArray(m, row);
    }
    cJSON_AddStringToObject(o, "status", c3->generation > 0u ? "ok" : magcal_status_str(magcal_cont3_status(c3)));
    cJSON_AddNumberToObject(o, "status_code", c3->generation > 0u ? 0.0 : (double)magcal_cont3_status(c3));
    cJSON_AddStringToObject(o, "mode", "3d");
    cJSON_AddItemToObject(o, "offset", off);
    cJSON_AddItemToObject(o, "matrix", m);
    cJSON_AddNumberToObject(o, "field", (double)c3->cal.field);
    cJSON_AddNumberToObject(o, "generation", (double)c3->generation);
    cJSON_AddStringToObject(o, "last_solve_status", magcal_status_str(magcal_cont3_status(c3)));
    if (c3->generation > 0u) {
        /* the fit of the calibration in force */
        cJSON_AddNumberToObject(o, "n_used", (double)r->n_used);
        cJSON_AddNumberToObject(o, "n_outliers", (double)r->n_rejected);
        cJSON_AddNumberToObject(o, "coverage", (double)r->coverage);
        cJSON_AddNumberToObject(o, "residual_rel", (double)(r->residual_rms / r->cal.field));
        cJSON_AddNumberToObject(o, "bfield_spread_all_rows", stream3_spread(d, &c3->cal));
    }
    if (c3->generation > 0u && isfinite(stream3_est_err(r))) {
        cJSON_AddNumberToObject(o, "est_heading_err_deg", stream3_est_err(r));
    } else {
        cJSON_AddNullToObject(o, "est_heading_err_deg"); /* none, or the calibration from flash */
    }
}

/* One row's heading; 1 when the heading was computed (tilt failures give 0: no heading). */
static int stream3_heading(const magcal_replay_csv_t *d, size_t i, double ascale, const magcal_vec3_t *m,
                           double decl, magcal_cont3_heading_t *hd)
{
    magcal_vec3_t a;
    const magcal_vec3_t *ap = NULL;
    if (ascale > 0.0) {
        const double ax = d->col[MAGCAL_REPLAY_COL_AX][i], ay = d->col[MAGCAL_REPLAY_COL_AY][i],
                     az = d->col[MAGCAL_REPLAY_COL_AZ][i];
        if (!(isfinite(ax) && isfinite(ay) && isfinite(az))) {
            return 0;
        }
        a.x = (float)(ax * ascale);
        a.y = (float)(ay * ascale);
        a.z = (float)(az * ascale);
        ap = &a;
    }
    return magcal_cont3_heading(&g_c3, m, ap, (float)decl, hd) == MAGCAL_OK;
}

/* The event of one step's outcome (idle and in progress: none). */
static void stream3_event(cJSON *ev, size_t row, magcal_cont3_outcome_t oc)
{
    if (oc == MAGCAL_CONT3_ADOPTED) {
        add_event(ev, row, "adopted", "ok", stream3_est_err(&g_c3.last));
    } else if (oc == MAGCAL_CONT3_REFUSED) {
        add_event(ev, row, "refused", magcal_status_str(magcal_cont3_status(&g_c3)), stream3_est_err(&g_c3.cand));
    } else if (oc == MAGCAL_CONT3_FAILED) {
        add_event(ev, row, "refused", magcal_status_str(magcal_cont3_status(&g_c3)), NAN);
    } else if (oc == MAGCAL_CONT3_CHANGE) {
        add_event(ev, row, "change", "changed", NAN);
    } else {
        /* idle or in progress */
    }
}

static int replay_stream3(const char *path, const char *hpath, int json, double decl, float range,
                          unsigned steps_per_row)
{
    magcal_replay_csv_t d;
    char err[MAGCAL_REPLAY_CSV_ERR_LEN];
    magcal_cont3_cfg_t cfg = MAGCAL_CONT3_CFG_DEFAULT;
    FILE *hf = NULL;
    cJSON *root;
    cJSON *ev;
    size_t i, trusted = 0u, ref_n = 0u, no_att = 0u;
    double ref_ss = 0.0, ascale;
    int prev_dist = 0;
    const double *ref;
    const double *tc;
    cfg.intake.range_limit = range;
    memset(&d, 0, sizeof d);
    if (magcal_replay_csv_read(path,
                               MAGCAL_REPLAY_COL_BIT(MAGCAL_REPLAY_COL_MX) | MAGCAL_REPLAY_COL_BIT(MAGCAL_REPLAY_COL_MY) |
                                   MAGCAL_REPLAY_COL_BIT(MAGCAL_REPLAY_COL_MZ),
                               &d, err, sizeof err) != MAGCAL_OK) {
        fprintf(stderr, "magcal-replay: %s\n", err);
        return 2;
    }
    if (magcal_cont3_init(&g_c3, &cfg, NULL, g_slots3, RS3_SLOTS, g_buf3, g_work3, sizeof g_work3) != MAGCAL_OK) {
        magcal_replay_csv_free(&d);
        return 5;
    }
    ascale = stream3_accel_scale(&d);
    if (ascale == 0.0 && d.col[MAGCAL_REPLAY_COL_AX] != NULL) {
        fprintf(stderr, "magcal-replay: %s: accelerometer unit not g, mg or m/s^2 (raw counts?): "
                        "headings use the level formula\n", path);
    }
    ref = d.col[MAGCAL_REPLAY_COL_HEADING_REF];
    tc = d.col[MAGCAL_REPLAY_COL_T];
    if (stream_headings_open(hpath, ref != NULL, &hf) == 0) {
        magcal_replay_csv_free(&d);
        return 4;
    }
    root = cJSON_CreateObject();
    ev = cJSON_CreateArray();
    for (i = 0u; i < d.n_rows; ++i) {
        magcal_vec3_t m;
        magcal_cont3_heading_t hd;
        uint32_t t_ms;
        unsigned k;
        const char *trust;
        int have;
        m.x = (float)d.col[MAGCAL_REPLAY_COL_MX][i];
        m.y = (float)d.col[MAGCAL_REPLAY_COL_MY][i];
        m.z = (float)d.col[MAGCAL_REPLAY_COL_MZ][i];
        t_ms = stream_row_ms(tc, i);
        (void)magcal_cont3_push(&g_c3, &m, t_ms);
        for (k = 0u; k < steps_per_row; ++k) {
            stream3_event(ev, i, magcal_cont3_step(&g_c3));
        }
        have = stream3_heading(&d, i, ascale, &m, decl, &hd);
        if (!have) {
            /* no attitude (tilt gate: accelerating, free fall, gimbal) or no field: no heading */
            hd.heading_deg = NAN;
            hd.raw_heading_deg = NAN;
            hd.generation = g_c3.generation;
            no_att++;
            trust = "no_heading";
            prev_dist = 0;
        } else {
            trust = magcal_trust_str(hd.trust);
            if (hd.trust == MAGCAL_TRUST_DISTURBED && !prev_dist) {
                add_event(ev, i, "disturbance", "disturbed", NAN);
            }
            prev_dist = hd.trust == MAGCAL_TRUST_DISTURBED;
            if (hd.trust == MAGCAL_TRUST_OK) {
                ++trusted;
            }
        }
        if (hf != NULL) {
            fprintf(hf, "%zu,%.4f,%.4f,%s,%u", i, (double)hd.raw_heading_deg, (double)hd.heading_deg, trust,
                    (unsigned)hd.generation);
            if (ref != NULL) {
                fprintf(hf, ",%.4f,%.4f", ref[i], wrap180((double)hd.heading_deg - ref[i]));
            }
            fputc('\n', hf);
        }
        if (ref != NULL && have && hd.trust == MAGCAL_TRUST_OK && isfinite(ref[i])) {
            double e = wrap180((double)hd.heading_deg - ref[i]);
            ref_ss += e * e;
            ref_n++;
        }
    }
    /* after the last row the firmware's loop goes on: the solve under way ends (events at row =
     * rows); bounded (a sliced solve is a few hundred steps) */
    for (i = 0u; i < 1000000u && g_c3.stage != 0u; ++i) {
        stream3_event(ev, d.n_rows, magcal_cont3_step(&g_c3));
    }
    add_cal3(root, &g_c3, &d);
    cJSON_AddStringToObject(root, "file", path);
    cJSON_AddNumberToObject(root, "rows", (double)d.n_rows);
    cJSON_AddNumberToObject(root, "trusted_rows", (double)trusted);
    cJSON_AddNumberToObject(root, "no_heading_rows", (double)no_att);
    cJSON_AddBoolToObject(root, "tilt_compensated", ascale > 0.0);
    stream_report_tail(root, g_c3.solves, g_c3.changes, g_c3.dropped, ref_ss, ref_n, ev);
    if (json) {
        stream_print_json(root);
    } else {
        printf("stream 3d: %zu rows, %zu trusted, %u adoptions, %u solves, %u changes\n", d.n_rows, trusted,
               (unsigned)g_c3.generation, (unsigned)g_c3.solves, (unsigned)g_c3.changes);
    }
    cJSON_Delete(root);
    if (hf != NULL && fclose(hf) != 0) {
        magcal_replay_csv_free(&d);
        return 4;
    }
    magcal_replay_csv_free(&d);
    return g_c3.has_cal != 0u ? 0 : 3;
}

/* The text report of a 2-D stream replay: events, the calibration in force, rows by trust. */
static void print_stream_text(const char *file, const magcal_replay_csv_t *d, const cJSON *ev,
                              const size_t by_trust[6], unsigned steps_per_row, size_t tail)
{
    const cJSON *e;
    printf("magcal-replay --stream: %s\n", file);
    printf("  %zu rows in file order: push + %u step() per row at the default configuration "
           "(budget %u M4F instructions per step), then %zu steps after the last row\n",
           d->n_rows, steps_per_row, (unsigned)g_cc.cfg.step_budget, tail);
    printf("  events (row, event, status, estimated heading error):\n");
    cJSON_ArrayForEach(e, ev)
    {
        const cJSON *err = cJSON_GetObjectItemCaseSensitive(e, "heading_err_deg");
        const char *what = cJSON_GetObjectItemCaseSensitive(e, "event")->valuestring;
        if (strcmp(what, "disturbance") == 0) {
            continue; /* counted below */
        }
        printf("    %6d  %-8s %-40s", cJSON_GetObjectItemCaseSensitive(e, "row")->valueint, what,
               cJSON_GetObjectItemCaseSensitive(e, "status")->valuestring);
        if (cJSON_IsNumber(err)) {
            printf(" %.2f deg", err->valuedouble);
        }
        putchar('\n');
    }
    if (g_cc.generation > 0u) {
        printf("  calibration in force (generation %u): offset (%.5g, %.5g), matrix [[%.5f, %.5f], [%.5f, %.5f]], "
               "radius %.5g, estimated heading error %.2f deg\n",
               (unsigned)g_cc.generation, (double)g_cc.cal.offset.x, (double)g_cc.cal.offset.y,
               (double)g_cc.cal.m[0][0], (double)g_cc.cal.m[0][1], (double)g_cc.cal.m[1][0],
               (double)g_cc.cal.m[1][1], (double)g_cc.cal.radius, (double)g_cc.adopted_err);
    } else {
        printf("  no calibration adopted (last solve: %s)\n", magcal_status_str(g_cc.last_status));
    }
    printf("  headings: %zu ok, %zu uncalibrated, %zu disturbed, %zu changed, %zu coarse, %zu tilted; %u solves, %u changes, "
           "%u ring overflows\n",
           by_trust[MAGCAL_TRUST_OK], by_trust[MAGCAL_TRUST_UNCALIBRATED], by_trust[MAGCAL_TRUST_DISTURBED],
           by_trust[MAGCAL_TRUST_CHANGED], by_trust[MAGCAL_TRUST_COARSE],
           by_trust[MAGCAL_TRUST_TILTED], (unsigned)g_cc.solves, (unsigned)g_cc.changes,
           (unsigned)g_cc.dropped);
}

/* Level samples held by the store at the end (the slots' level bit, intake.h). */
static uint32_t stream_store_level(const magcal_intake_t *st)
{
    uint32_t b, k, n = 0u;
    for (b = 0u; b < st->n_bins; ++b) {
        for (k = 0u; k < st->count[b]; ++k) {
            n += (st->slots[b * st->cfg.per_bin + k].seq >> 31) & 1u;
        }
    }
    return n;
}

/* --install REC: a 2-D flash record (magcal/record.h) read and checked; 0 ok, else said on stderr. */
static int stream_record_read(const char *path, magcal_record_t *rec)
{
    uint8_t page[MAGCAL_RECORD_LEN];
    FILE *f = fopen(path, "rb");
    size_t n = 0u;
    magcal_status_t st;
    if (f != NULL) {
        n = fread(page, 1u, sizeof page, f);
        (void)fclose(f);
    }
    st = magcal_record_unpack(page, n, rec);
    if (f == NULL || st != MAGCAL_OK || rec->kind != MAGCAL_RECORD_KIND_2D) {
        fprintf(stderr, "magcal-replay: --install %s: %s\n", path,
                f == NULL ? "cannot be read" : (st != MAGCAL_OK ? magcal_status_str(st) : "not a 2-D record"));
        return 1;
    }
    return 0;
}

/* --save REC: the full calibration in force at the end as a 2-D record (the quality figures of its
 * adoption); 0 ok (or nothing to save: said on stderr), 1 when it cannot be written (said). */
static int stream_record_write(const char *path, const magcal_cont_t *cc)
{
    magcal_record_t rec;
    char err[256];
    if (cc->has_cal == 0u || cc->cal_coarse != 0u) {
        fprintf(stderr, "magcal-replay: --save %s: no full calibration in force, nothing written\n", path);
        return 0;
    }
    (void)memset(&rec, 0, sizeof rec);
    rec.kind = MAGCAL_RECORD_KIND_2D;
    rec.unit = MAGCAL_RECORD_UNIT_RAW;
    rec.n_used = cc->last.used;
    rec.est_heading_err_deg = cc->adopted_err;
    rec.radius = cc->cal_raw_radius;
    rec.residual_rms = 0.0f;
    rec.coverage = 360.0f;
    rec.cal2d = cc->cal;
    (void)magcal_cont_tilt_state(cc, &rec.tilt_k, &rec.tilt_levelled); /* kept with it (record.h) */
    if (replay_record_write(path, "--save", &rec, err, sizeof err) != REPLAY_EXIT_OK) {
        fprintf(stderr, "magcal-replay: %s\n", err);
        return 1;
    }
    return 0;
}

/* One step's outcome as an event of the JSON report. */
static void stream_event(cJSON *ev, size_t row, magcal_cont_outcome_t oc)
{
    if (oc == MAGCAL_CONT_ADOPTED) {
        add_event(ev, row, "adopted", g_cc.cal_coarse != 0u ? "coarse" : "ok", (double)g_cc.last.est_heading_err_deg);
    } else if (oc == MAGCAL_CONT_REFUSED || oc == MAGCAL_CONT_FAILED) {
        add_event(ev, row, "refused", magcal_status_str(g_cc.last.status), (double)g_cc.last.est_heading_err_deg);
    } else if (oc == MAGCAL_CONT_CHANGE) {
        add_event(ev, row, "change", "changed", NAN);
    } else {
        /* idle or in progress */
    }
}

/* An option's degrees, 0..max (one number, nothing else): 1 and *out set, else 0 (said on stderr). */
static int parse_deg_opt(const char *name, const char *arg, double max, float *out)
{
    char *end = NULL;
    const double v = strtod(arg, &end);
    if (end == arg || *end != '\0' || !(v >= 0.0 && v <= max)) {
        fprintf(stderr, "magcal-replay: %s needs degrees 0..%g, got \"%s\"\n", name, max, arg);
        return 0;
    }
    *out = (float)v;
    return 1;
}

/* "A[,B[,...]]": up to max numbers separated by commas, nothing else (strtod each): how many
 * were read, 0 when malformed (an empty field, a trailing comma or other characters). */
static int parse_num_list(const char *s, double *v, int max)
{
    const char *p = s;
    int n = 0;
    for (;;) {
        char *end = NULL;
        v[n] = strtod(p, &end);
        if (end == p) {
            return 0;
        }
        n++;
        if (*end == '\0') {
            return n;
        }
        if (*end != ',' || n >= max) {
            return 0;
        }
        p = end + 1;
    }
}

int replay_stream_main(int argc, char **argv)
{
    static const struct option k_opts[] = {{"stream", no_argument, NULL, 's'},
                                           {"mode", required_argument, NULL, 'm'},
                                           {"headings", required_argument, NULL, 'H'},
                                           {"json", no_argument, NULL, 'j'},
                                           {"declination", required_argument, NULL, 'd'},
                                           {"range", required_argument, NULL, 'r'},
                                           {"steps-per-row", required_argument, NULL, 'k'},
                                           {"coarse", required_argument, NULL, 'c'},
                                           {"arc", required_argument, NULL, 'a'},
                                           {"continuity", required_argument, NULL, 'g'},
                                           {"no-tilt", no_argument, NULL, 'T'},
                                           {"level-tilt", required_argument, NULL, 'L'},
                                           {"install", required_argument, NULL, 'I'},
                                           {"save", required_argument, NULL, 'S'},
                                           {"no-gyro", no_argument, NULL, 'G'},
                                           {"gyro-unit", required_argument, NULL, 'U'},
                                           {"gyro-gravity", no_argument, NULL, 'A'},
                                           {"ok-max-err", required_argument, NULL, 'O'},
                                           {"help", no_argument, NULL, 'h'},
                                           {NULL, 0, NULL, 0}};
    const char *hpath = NULL;
    int json = 0;
    double decl = 0.0;
    int opt;
    magcal_replay_csv_t d;
    char err[MAGCAL_REPLAY_CSV_ERR_LEN];
    magcal_cont_cfg_t cfg = MAGCAL_CONT_CFG_DEFAULT;
    FILE *hf = NULL;
    cJSON *root;
    cJSON *ev;
    size_t i, trusted = 0u, ref_n = 0u;
    double ref_ss = 0.0;
    int prev_dist = 0;
    const double *ref;
    const double *tc;
    int mode3 = 0;
    unsigned steps_per_row = 1u;
    size_t by_trust[6] = {0u, 0u, 0u, 0u, 0u, 0u};
    unsigned k;
    size_t tail;
    int no_tilt = 0;
    double gscale = 0.0; /* 2-D gravity feed: accelerometer unit to g, 0 = not fed */
    const char *install_path = NULL; /* --install REC: a calibration restored from flash at init */
    const char *save_path = NULL;    /* --save REC: the calibration in force at the end, as a record */
    magcal_record_t rec_in;
    int no_gyro = 0;
    double wscale = 1.0; /* gyro unit to rad/s */
    int gyro = 0;        /* 1: rows pushed with magcal_cont_push_imu */

    optind = 1;
    while ((opt = getopt_long(argc, argv, "h", k_opts, NULL)) != -1) {
        switch (opt) {
        case 's':
            break;
        case 'm':
            if (strcmp(optarg, "3d") == 0) {
                mode3 = 1;
            } else if (strcmp(optarg, "2d") == 0) {
                mode3 = 0;
            } else {
                fprintf(stderr, "magcal-replay: --stream --mode must be 2d or 3d, got \"%s\"\n", optarg);
                return 1;
            }
            break;
        case 'H':
            hpath = optarg;
            break;
        case 'j':
            json = 1;
            break;
        case 'd': {
            char *end = NULL;
            decl = strtod(optarg, &end);
            if (end == optarg || *end != '\0' || !isfinite(decl)) {
                fprintf(stderr, "magcal-replay: --declination needs a number, got \"%s\"\n", optarg);
                return 1;
            }
            break;
        }
        case 'r': {
            char *end = NULL;
            double v = strtod(optarg, &end);
            if (end == optarg || *end != '\0' || !(v > 0.0) || !isfinite(v)) {
                fprintf(stderr, "magcal-replay: --range needs a positive number, got \"%s\"\n", optarg);
                return 1;
            }
            cfg.intake.range_limit = (float)v;
            break;
        }
        case 'k': {
            char *end = NULL;
            unsigned long v = strtoul(optarg, &end, 10);
            if (end == optarg || *end != '\0' || v < 1ul || v > 64ul) {
                fprintf(stderr, "magcal-replay: --steps-per-row needs an integer 1..64, got \"%s\"\n", optarg);
                return 1;
            }
            steps_per_row = (unsigned)v;
            break;
        }
        case 'c': {
            double a[2] = {0.0, (double)cfg.coarse_max_err_deg};
            const int n = parse_num_list(optarg, a, 2);
            if (n < 1 || !(a[0] > 0.0 && a[0] <= 360.0) || !(a[1] > 0.0) || !isfinite(a[1])) {
                fprintf(stderr, "magcal-replay: --coarse needs DEG (0..360] [,TOL > 0], got \"%s\"\n", optarg);
                return 1;
            }
            cfg.coarse_coverage_deg = (float)a[0];
            cfg.coarse_max_err_deg = (float)a[1];
            break;
        }
        case 'a': {
            double a[3] = {0.0, (double)cfg.arc_max_err_deg, (double)cfg.arc_model_deg};
            const int n = parse_num_list(optarg, a, 3);
            if (n < 1 || !(a[0] > 0.0 && a[0] <= 360.0) || !(a[1] > 0.0) || !isfinite(a[1]) || !(a[2] >= 0.0) ||
                !isfinite(a[2])) {
                fprintf(stderr, "magcal-replay: --arc needs DEG (0..360] [,TOL > 0 [,MODEL >= 0]], got \"%s\"\n", optarg);
                return 1;
            }
            cfg.arc_coverage_deg = (float)a[0];
            cfg.arc_max_err_deg = (float)a[1];
            cfg.arc_model_deg = (float)a[2];
            break;
        }
        case 'g':
            if (strcmp(optarg, "0") != 0 && strcmp(optarg, "1") != 0) {
                fprintf(stderr, "magcal-replay: --continuity needs 0 or 1, got \"%s\"\n", optarg);
                return 1;
            }
            cfg.continuity = (uint8_t)(optarg[0] - '0');
            break;
        case 'T':
            no_tilt = 1;
            break;
        case 'L':
            if (parse_deg_opt("--level-tilt", optarg, 30.0, &cfg.intake.tilt_limit_deg) == 0) {
                return 1;
            }
            break;
        case 'I':
            install_path = optarg;
            break;
        case 'S':
            save_path = optarg;
            break;
        case 'G':
            no_gyro = 1;
            break;
        case 'A':
            cfg.gyro_gravity = 1u;
            break;
        case 'O':
            if (parse_deg_opt("--ok-max-err", optarg, 90.0, &cfg.ok_max_err_deg) == 0) {
                return 1;
            }
            break;
        case 'U':
            if (strcmp(optarg, "rads") == 0) {
                wscale = 1.0;
            } else if (strcmp(optarg, "dps") == 0) {
                wscale = 3.14159265358979323846 / 180.0;
            } else {
                fprintf(stderr, "magcal-replay: --gyro-unit must be rads or dps, got \"%s\"\n", optarg);
                return 1;
            }
            break;
        case 'h':
            fputs(k_stream_usage, stdout);
            return 0;
        default:
            fputs(k_stream_usage, stderr);
            return 1;
        }
    }
    if (optind != argc - 1) {
        fputs(k_stream_usage, stderr);
        return 1;
    }
    if (mode3) {
        return replay_stream3(argv[optind], hpath, json, decl, cfg.intake.range_limit, steps_per_row);
    }
    memset(&d, 0, sizeof d);
    if (magcal_replay_csv_read(argv[optind],
                               MAGCAL_REPLAY_COL_BIT(MAGCAL_REPLAY_COL_MX) | MAGCAL_REPLAY_COL_BIT(MAGCAL_REPLAY_COL_MY),
                               &d, err, sizeof err) != MAGCAL_OK) {
        fprintf(stderr, "magcal-replay: %s\n", err);
        return 2;
    }
    if (install_path != NULL && stream_record_read(install_path, &rec_in) != 0) {
        magcal_replay_csv_free(&d);
        return 1;
    }
    if (magcal_cont_init(&g_cc, &cfg, install_path != NULL ? &rec_in.cal2d : NULL, g_slots, RS_SLOTS, g_buf, g_work,
                         sizeof g_work) != MAGCAL_OK) {
        magcal_replay_csv_free(&d);
        return 5;
    }
    if (install_path != NULL && rec_in.tilt_k != 0.0f && !no_tilt) {
        /* the tilt compensation kept with the restored calibration (record.h tilt_k) */
        const magcal_status_t rs = magcal_cont_restore_tilt(&g_cc, rec_in.tilt_k, rec_in.tilt_levelled);
        if (rs != MAGCAL_OK) {
            fprintf(stderr, "magcal-replay: --install %s: its tilt compensation is refused: %s\n", install_path,
                    magcal_status_str(rs));
            magcal_replay_csv_free(&d);
            return 1;
        }
    }
    ref = d.col[MAGCAL_REPLAY_COL_HEADING_REF];
    tc = d.col[MAGCAL_REPLAY_COL_T];
    if (!no_tilt) {
        gscale = stream3_accel_scale(&d); /* the unit detection of --mode 3d (and the batch mode) */
        if (gscale == 0.0 && d.col[MAGCAL_REPLAY_COL_AX] != NULL) {
            fprintf(stderr, "magcal-replay: %s: accelerometer unit not g, mg or m/s^2 (raw counts?): "
                            "no gravity fed (--no-tilt to silence)\n", argv[optind]);
        }
    }
    gyro = !no_gyro && d.col[MAGCAL_REPLAY_COL_GX] != NULL && d.col[MAGCAL_REPLAY_COL_GY] != NULL &&
           d.col[MAGCAL_REPLAY_COL_GZ] != NULL;
    if (stream_headings_open(hpath, ref != NULL, &hf) == 0) {
        magcal_replay_csv_free(&d);
        return 4;
    }
    root = cJSON_CreateObject();
    ev = cJSON_CreateArray();
    for (i = 0u; i < d.n_rows; ++i) {
        magcal_vec3_t m;
        magcal_cont_heading_t hd;
        uint32_t t_ms;
        double mz = d.col[MAGCAL_REPLAY_COL_MZ] != NULL ? d.col[MAGCAL_REPLAY_COL_MZ][i] : 0.0;
        m.x = (float)d.col[MAGCAL_REPLAY_COL_MX][i];
        m.y = (float)d.col[MAGCAL_REPLAY_COL_MY][i];
        m.z = isfinite(mz) ? (float)mz : 0.0f;
        t_ms = stream_row_ms(tc, i);
        {
            /* a non-finite gravity row is pushed without a tilt code (push_g checks it) */
            magcal_vec3_t g = {0.0f, 0.0f, 0.0f};
            if (gscale > 0.0) {
                g.x = (float)(d.col[MAGCAL_REPLAY_COL_AX][i] * gscale);
                g.y = (float)(d.col[MAGCAL_REPLAY_COL_AY][i] * gscale);
                g.z = (float)(d.col[MAGCAL_REPLAY_COL_AZ][i] * gscale);
            }
            if (gyro) {
                /* the gyro heading check (continuous.h): rates in rad/s, gravity when fed */
                magcal_vec3_t w;
                w.x = (float)(d.col[MAGCAL_REPLAY_COL_GX][i] * wscale);
                w.y = (float)(d.col[MAGCAL_REPLAY_COL_GY][i] * wscale);
                w.z = (float)(d.col[MAGCAL_REPLAY_COL_GZ][i] * wscale);
                (void)magcal_cont_push_imu(&g_cc, &m, gscale > 0.0 ? &g : NULL, &w, t_ms);
            } else if (gscale > 0.0) {
                (void)magcal_cont_push_g(&g_cc, &m, &g, t_ms);
            } else {
                (void)magcal_cont_push(&g_cc, &m, t_ms);
            }
        }
        for (k = 0u; k < steps_per_row; ++k) {
            const uint32_t shifts = g_cc.shifts;
            stream_event(ev, i, magcal_cont_step(&g_cc));
            if (g_cc.shifts != shifts) {
                add_event(ev, i, "shift", "level shift", NAN); /* continuous.h "Level shift" */
            }
        }
        if (magcal_cont_heading(&g_cc, &m, (float)decl, &hd) != MAGCAL_OK) {
            hd.trust = MAGCAL_TRUST_DISTURBED;
            hd.heading_deg = NAN;
            hd.raw_heading_deg = NAN;
            hd.generation = g_cc.generation;
        }
        if (hd.trust == MAGCAL_TRUST_DISTURBED && !prev_dist) {
            add_event(ev, i, "disturbance", "disturbed", NAN);
        }
        prev_dist = hd.trust == MAGCAL_TRUST_DISTURBED;
        if (hd.trust == MAGCAL_TRUST_OK) {
            ++trusted;
        }
        if ((unsigned)hd.trust < 5u) {
            by_trust[(unsigned)hd.trust]++;
        }
        if (hf != NULL) {
            fprintf(hf, "%zu,%.4f,%.4f,%s,%u", i, (double)hd.raw_heading_deg, (double)hd.heading_deg,
                    magcal_trust_str(hd.trust), (unsigned)hd.generation);
            if (ref != NULL) {
                double e = wrap180((double)hd.heading_deg - ref[i]);
                fprintf(hf, ",%.4f,%.4f", ref[i], e);
            }
            fputc('\n', hf);
        }
        if (ref != NULL && hd.trust == MAGCAL_TRUST_OK && isfinite(ref[i])) {
            double e = wrap180((double)hd.heading_deg - ref[i]);
            ref_ss += e * e;
            ref_n++;
        }
    }
    /* After the last row the firmware's loop goes on: step (no pushes) until the calibrator has
     * nothing left to do: no solve under way and TAIL_IDLE steps in a row IDLE (a refused or
     * failed solve may be followed by one on the samples stored while it ran; the sliced coverage
     * count that decides it takes a few steps). Events at row = rows ("after the dump"); bounded
     * (a solve is a few thousand steps). */
    {
        unsigned idle = 0u;
        for (tail = 0u; tail < 1000000u && idle < TAIL_IDLE; ++tail) {
            const magcal_cont_outcome_t o = magcal_cont_step(&g_cc);
            stream_event(ev, d.n_rows, o);
            idle = (o == MAGCAL_CONT_IDLE && g_cc.stage == 0u) ? idle + 1u : 0u;
        }
    }
    add_cal(root, &g_cc);
    cJSON_AddStringToObject(root, "file", argv[optind]);
    cJSON_AddNumberToObject(root, "steps_per_row", (double)steps_per_row);
    cJSON_AddNumberToObject(root, "tail_steps", (double)tail);
    cJSON_AddNumberToObject(root, "rows", (double)d.n_rows);
    cJSON_AddNumberToObject(root, "trusted_rows", (double)trusted);
    cJSON_AddBoolToObject(root, "gravity_fed", gscale > 0.0);
    if (gscale > 0.0) {
        cJSON_AddNumberToObject(root, "level_tilt_deg", (double)g_cc.cfg.intake.tilt_limit_deg);
        cJSON_AddNumberToObject(root, "gravity_rows", (double)g_cc.g_pushed);
        cJSON_AddNumberToObject(root, "level_rows", (double)g_cc.g_level);
        cJSON_AddNumberToObject(root, "store_level", (double)stream_store_level(&g_cc.store));
        /* tilt compensation (continuous.h): the estimated raw shift per unit tilt, rows levelled */
        cJSON_AddNumberToObject(root, "tilt_comp_k", g_cc.tc_ok != 0u ? (double)g_cc.tc_k : 0.0);
        cJSON_AddNumberToObject(root, "tilt_comp_rho", (double)g_cc.tc_rho); /* the share of the tilt z confirms */
        cJSON_AddNumberToObject(root, "tilt_comp_pairs", (double)g_cc.tc_n);
        cJSON_AddNumberToObject(root, "levelled_rows", (double)g_cc.tc_levelled);
        cJSON_AddNumberToObject(root, "relevels", (double)g_cc.relevels); /* compensation on under an unlevelled calibration */
        cJSON_AddNumberToObject(root, "cal_levels", (double)g_cc.levels); /* such calibrations levelled by their fit tilt */
    }
    cJSON_AddBoolToObject(root, "gyro_fed", gyro);
    if (gyro) {
        /* the gyro heading check (continuous.h): flags raised, the sign in force, the bias */
        cJSON_AddNumberToObject(root, "rate_flags", (double)g_cc.rj_flags);
        cJSON_AddNumberToObject(root, "rate_sign", (double)g_cc.rj_sgn);
        cJSON_AddNumberToObject(root, "rate_bias_dps", (double)g_cc.rj_b);
        cJSON_AddBoolToObject(root, "gravity_locked", g_cc.ga_lock != 0u);
        cJSON_AddNumberToObject(root, "gravity_unlocks", (double)g_cc.ga_unlocks);
    }
    cJSON_AddNumberToObject(root, "shifts", (double)g_cc.shifts); /* level shifts (continuous.h) */
    cJSON_AddNumberToObject(root, "shift_refused", (double)g_cc.shift_refused);
    cJSON_AddNumberToObject(root, "continuity_refused", (double)g_cc.cg_refused); /* continuity gate */
    stream_report_tail(root, g_cc.solves, g_cc.changes, g_cc.dropped, ref_ss, ref_n, ev);
    if (json) {
        stream_print_json(root);
    } else {
        print_stream_text(argv[optind], &d, ev, by_trust, steps_per_row, tail);
    }
    cJSON_Delete(root);
    if (hf != NULL && fclose(hf) != 0) {
        magcal_replay_csv_free(&d);
        return 4;
    }
    magcal_replay_csv_free(&d);
    if (save_path != NULL && stream_record_write(save_path, &g_cc) != 0) {
        return 4;
    }
    return g_cc.has_cal != 0u ? 0 : 3;
}
