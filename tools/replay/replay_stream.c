/*
 * magcal-replay --stream [--mode 2d] [--headings OUT.csv] [--json] [--declination DEG] DUMP.csv
 * Feeds every row (no limit, no decimation) through magcal_cont_push + magcal_cont_step at the
 * default configuration, then magcal_cont_heading for the row. Headings CSV:
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
#include "replay_csv.h"

#define RS_SECTORS 36u
#define RS_PER_BIN 8u
#define RS_SLOTS MAGCAL_CONT_SLOTS(RS_SECTORS, RS_PER_BIN)

static magcal_intake_slot_t g_slots[RS_SLOTS];
static magcal_vec2_t g_buf[RS_SLOTS];
static MAGCAL_CALIBRATOR_WORKSPACE_DECLARE(g_work, RS_SLOTS);
static magcal_cont_t g_cc;

static const char k_stream_usage[] =
    "usage: magcal-replay --stream [--mode 2d] [--headings OUT.csv] [--json] [--declination DEG]\n"
    "                        [--range R] DUMP.csv   (R: the sensor's declared range, dump unit)\n"
    "  every row in file order through magcal_cont_push + magcal_cont_step (default budget) and\n"
    "  magcal_cont_heading; --headings: index,raw_heading_deg,heading_deg,trust,generation\n"
    "  [,heading_ref_deg,error_deg]; --json: calibration in force at the end, events, rows, trusted_rows\n";

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

int replay_stream_main(int argc, char **argv)
{
    static const struct option k_opts[] = {{"stream", no_argument, NULL, 's'},
                                           {"mode", required_argument, NULL, 'm'},
                                           {"headings", required_argument, NULL, 'H'},
                                           {"json", no_argument, NULL, 'j'},
                                           {"declination", required_argument, NULL, 'd'},
                                           {"range", required_argument, NULL, 'r'},
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

    optind = 1;
    while ((opt = getopt_long(argc, argv, "h", k_opts, NULL)) != -1) {
        switch (opt) {
        case 's':
            break;
        case 'm':
            if (strcmp(optarg, "2d") != 0) {
                fprintf(stderr, "magcal-replay: --stream supports --mode 2d only (3d: not built yet)\n");
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
    memset(&d, 0, sizeof d);
    if (magcal_replay_csv_read(argv[optind],
                               MAGCAL_REPLAY_COL_BIT(MAGCAL_REPLAY_COL_MX) | MAGCAL_REPLAY_COL_BIT(MAGCAL_REPLAY_COL_MY),
                               &d, err, sizeof err) != MAGCAL_OK) {
        fprintf(stderr, "magcal-replay: %s\n", err);
        return 2;
    }
    if (magcal_cont_init(&g_cc, &cfg, NULL, g_slots, RS_SLOTS, g_buf, g_work, sizeof g_work) != MAGCAL_OK) {
        magcal_replay_csv_free(&d);
        return 5;
    }
    if (hpath != NULL) {
        hf = fopen(hpath, "w");
        if (hf == NULL) {
            fprintf(stderr, "magcal-replay: cannot write %s\n", hpath);
            magcal_replay_csv_free(&d);
            return 4;
        }
    }
    ref = d.col[MAGCAL_REPLAY_COL_HEADING_REF];
    tc = d.col[MAGCAL_REPLAY_COL_T];
    if (hf != NULL) {
        fprintf(hf, "index,raw_heading_deg,heading_deg,trust,generation%s\n",
                ref != NULL ? ",heading_ref_deg,error_deg" : "");
    }
    root = cJSON_CreateObject();
    ev = cJSON_CreateArray();
    for (i = 0u; i < d.n_rows; ++i) {
        magcal_vec3_t m;
        magcal_cont_heading_t hd;
        magcal_cont_outcome_t oc;
        uint32_t t_ms;
        double mz = d.col[MAGCAL_REPLAY_COL_MZ] != NULL ? d.col[MAGCAL_REPLAY_COL_MZ][i] : 0.0;
        m.x = (float)d.col[MAGCAL_REPLAY_COL_MX][i];
        m.y = (float)d.col[MAGCAL_REPLAY_COL_MY][i];
        m.z = isfinite(mz) ? (float)mz : 0.0f;
        if (tc != NULL && isfinite(tc[i]) && isfinite(tc[0])) {
            t_ms = (uint32_t)(int64_t)llround((tc[i] - tc[0]) * 1000.0);
        } else {
            t_ms = (uint32_t)(i * 20u); /* no time column: 50 Hz */
        }
        (void)magcal_cont_push(&g_cc, &m, t_ms);
        oc = magcal_cont_step(&g_cc);
        if (oc == MAGCAL_CONT_ADOPTED) {
            add_event(ev, i, "adopted", "ok", (double)g_cc.last.est_heading_err_deg);
        } else if (oc == MAGCAL_CONT_REFUSED || oc == MAGCAL_CONT_FAILED) {
            add_event(ev, i, "refused", magcal_status_str(g_cc.last.status),
                      (double)g_cc.last.est_heading_err_deg);
        } else if (oc == MAGCAL_CONT_CHANGE) {
            add_event(ev, i, "change", "changed", NAN);
        } else {
            /* idle or in progress */
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
    add_cal(root, &g_cc);
    cJSON_AddStringToObject(root, "file", argv[optind]);
    cJSON_AddNumberToObject(root, "rows", (double)d.n_rows);
    cJSON_AddNumberToObject(root, "trusted_rows", (double)trusted);
    cJSON_AddNumberToObject(root, "solves", (double)g_cc.solves);
    cJSON_AddNumberToObject(root, "changes", (double)g_cc.changes);
    cJSON_AddNumberToObject(root, "dropped", (double)g_cc.dropped);
    if (ref_n > 0u) {
        cJSON_AddNumberToObject(root, "heading_rms_trusted_deg", sqrt(ref_ss / (double)ref_n));
    }
    cJSON_AddItemToObject(root, "events", ev);
    if (json) {
        char *s = cJSON_Print(root);
        if (s != NULL) {
            puts(s);
            free(s);
        }
    } else {
        printf("stream: %zu rows, %zu trusted, %u adoptions, %u solves, %u changes\n", d.n_rows, trusted,
               (unsigned)g_cc.generation, (unsigned)g_cc.solves, (unsigned)g_cc.changes);
    }
    cJSON_Delete(root);
    if (hf != NULL && fclose(hf) != 0) {
        magcal_replay_csv_free(&d);
        return 4;
    }
    magcal_replay_csv_free(&d);
    return g_cc.has_cal != 0u ? 0 : 3;
}
