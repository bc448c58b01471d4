/*
 * magcal-replay: replay a recorded (or generated) magnetometer dump through the magcal library,
 * over the same code path the MCU runs (replay port -> magcal_calibrator_poll -> run), and report
 * the calibration and its heading accuracy. Usage and every output field: docs/replay.md.
 */
#include <errno.h>
#include <getopt.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "magcal/aided.h"
#include "magcal/calibrator.h"
#include "magcal/ellipsoid.h"
#include "magcal/heading.h"
#include "magcal/status.h"
#include "magcal/tilt.h"
#include "magcal_port_replay.h"
#include "replay_cal.h"
#include "replay_checks.h"
#include "replay_csv.h"
#include "replay_modes.h"
#include "replay_record.h" /* --export-record (issue 15) */
#include "replay_report.h"
#include "replay_stream.h" /* --stream (issue 13) */

static const char k_usage[] =
    "usage: magcal-replay [options] DUMP.csv   (--opt value or --opt=value)\n"
    "  --stream            stream mode: every row through the continuous calibrator (--stream --help)\n"
    "  --cal-range A:B     rows [A,B) are the calibration segment (default: all rows;\n"
    "                      A: or :B leave one end open)\n"
    "  --filter MODE       optics (default, automatic parameters) | optics-classic | dbscan | none\n"
    "  --eps F             override the automatic OPTICS/DBSCAN radius (dump units, up to 1e15)\n"
    "  --min-pts N         override the automatic MinPts (2..MAGCAL_MAX_MIN_PTS)\n"
    "  --no-consensus      the plain least-squares baseline: unfiltered, unweighted 5-parameter fit of\n"
    "                      every calibration sample (same as --fit plain; --fit consensus = default)\n"
    "  --declination DEG   magnetic declination, east positive (default 0)\n"
    "  --plane XY|XZ|YZ    dump axes forming the horizontal plane (default XY; YX, ZX, ZY mirror)\n"
    "  --headings OUT.csv  per row: index,raw_heading_deg,heading_deg,outlier[,heading_ref_deg,error_deg]\n"
    "                      (aided: then a gate column: none|dop|raw|field|vector|skipped)\n"
    "  --json              the report as one JSON object on stdout (default: a readable table)\n"
    "  --mode 2d|3d|aided  2d (default): ellipse on the plane; 3d: ellipsoid on mx,my,mz;\n"
    "                      aided: INS/GNSS-aided 3-D calibration (roll/pitch/yaw, lat/lon/height)\n"
    "  --ref-rows A:B      rows [A,B) with heading_ref_deg fit a compass swing on the calibrated heading\n"
    "  --swing-model M     smith (default, 5 coefficients A..E) | fourier (adaptive order)\n"
    "  --tilt | --no-tilt  tilt compensation with ax,ay,az (default: on when ax,ay,az,mz exist)\n"
    "  --accel-unit U      g | mg | mps2 (default: detected from the median |a|)\n"
    "  --inclination DEG   2d + tilt: inclination giving the level vertical field (default 0)\n"
    "  --field-unit U      unit of mx,my,mz: uT | nT | gauss (reports and plots carry it; default:\n"
    "                      \"dump units\", aided: uT, compared with the WMM field)\n"
    "  --year Y            aided: decimal year of the dump (default: decimal_year column, else t as Unix time)\n"
    "  --aided-objective O aided: combined (vector + total-field residual, default) | vector\n"
    "  --model M           aided: reference field model wmm2025 (default, 2025-2030) | igrf14 (1900-2030)\n"
    "  --prior FILE.json   aided: prior (factory) calibration: the JSON report of a --mode 3d or aided run\n"
    "                      (keys matrix, offset; dump units) (default: identity G, zero V)\n"
    "  --export-record F   write the calibration's flash record (magcal/record.h, 96 bytes) to F\n"
    "  --sensor-id ID      sensor id stored in that record (decimal or 0x hex; default 0)\n"
    "  -h, --help          this text\n"
    "exit status: 0 ok, 1 usage, 2 input error, 3 calibration failed, 4 output error, 5 internal error\n";

static const double k_deg_per_rad = 57.295779513082320876798;

static int usage_error(const char *fmt, const char *arg)
{
    fprintf(stderr, "magcal-replay: ");
    fprintf(stderr, fmt, arg);
    fprintf(stderr, "\n%s", k_usage);
    return REPLAY_EXIT_USAGE;
}

static int parse_double(const char *s, double *out)
{
    char *end = NULL;
    double v;
    errno = 0;
    v = strtod(s, &end);
    if (end == s || *end != '\0' || errno != 0 || !isfinite(v)) {
        return -1;
    }
    *out = v;
    return 0;
}

static int parse_size(const char *s, size_t len, size_t *out)
{
    size_t i, v = 0u;
    if (len == 0u || len > 12u) {
        return -1;
    }
    for (i = 0u; i < len; ++i) {
        if (s[i] < '0' || s[i] > '9') {
            return -1;
        }
        v = v * 10u + (size_t)(s[i] - '0');
    }
    *out = v;
    return 0;
}

static double wrap180(double a)
{
    double w = fmod(a + 180.0, 360.0);
    if (w <= 0.0) {
        w += 360.0;
    }
    return w - 180.0;
}

static double wrap360(double a)
{
    double w = fmod(a, 360.0);
    if (w < 0.0) {
        w += 360.0;
    }
    return (w >= 360.0) ? 0.0 : w;
}

/* std/mean of |p| over the selected points; NaN when fewer than 2. */
static double spread(const double *rad, const unsigned char *use, size_t n)
{
    double s = 0.0, s2 = 0.0, mean;
    size_t i, k = 0u;
    for (i = 0u; i < n; ++i) {
        if (use[i]) {
            s += rad[i];
            k++;
        }
    }
    if (k < 2u || s <= 0.0) {
        return NAN;
    }
    mean = s / (double)k;
    for (i = 0u; i < n; ++i) {
        if (use[i]) {
            s2 += (rad[i] - mean) * (rad[i] - mean);
        }
    }
    return sqrt(s2 / (double)k) / mean;
}

/* Heading metrics over non-calibration rows with a reference (algorithms.md 9). */
static void heading_metrics(replay_report_t *r, const double *ref, const double *err,
                            const unsigned char *flag, size_t n_rows)
{
    double s = 0.0, s2 = 0.0, mx = 0.0;
    size_t i, g, n = 0u, distinct = 0u;
    double keys[REPLAY_MAX_REF_GROUPS];
    r->n_heading = 0u;
    r->n_heading_flagged = 0u;
    r->n_groups = 0u;
    r->by_ref_sectors = 0;
    /* distinct reference values (to 0.01 deg); too many -> 45-degree sectors */
    for (i = 0u; i < n_rows; ++i) {
        double key;
        if ((i >= r->cal_first && i < r->cal_end) || (i >= r->ref_first && i < r->ref_end) ||
            !isfinite(ref[i]) || !isfinite(err[i])) {
            continue;
        }
        key = floor(wrap360(ref[i]) * 100.0 + 0.5) / 100.0;
        for (g = 0u; g < distinct && keys[g] != key; ++g) {
        }
        if (g == distinct) {
            if (distinct == REPLAY_MAX_REF_GROUPS) {
                r->by_ref_sectors = 1;
                break;
            }
            keys[distinct++] = key;
        }
    }
    if (r->by_ref_sectors) {
        distinct = 8u;
        for (g = 0u; g < 8u; ++g) {
            keys[g] = 45.0 * (double)g;
        }
    }
    /* sort keys (insertion sort, at most REPLAY_MAX_REF_GROUPS) */
    for (g = 1u; g < distinct; ++g) {
        double k = keys[g];
        size_t j = g;
        while (j > 0u && keys[j - 1u] > k) {
            keys[j] = keys[j - 1u];
            --j;
        }
        keys[j] = k;
    }
    for (g = 0u; g < distinct; ++g) {
        r->groups[g].ref_deg = keys[g];
        r->groups[g].n = 0u;
        r->groups[g].rms_deg = 0.0;
        r->groups[g].bias_deg = 0.0;
        r->groups[g].max_abs_deg = 0.0;
    }
    for (i = 0u; i < n_rows; ++i) {
        double e, key;
        if ((i >= r->cal_first && i < r->cal_end) || (i >= r->ref_first && i < r->ref_end) ||
            !isfinite(ref[i]) || !isfinite(err[i])) {
            continue;
        }
        r->n_heading_flagged += (size_t)(flag[i] != 0u); /* counted, not excluded */
        e = err[i];
        s += e;
        s2 += e * e;
        mx = fmax(mx, fabs(e));
        n++;
        if (r->by_ref_sectors) {
            g = (size_t)floor(wrap360(ref[i] + 22.5) / 45.0) % 8u;
        } else {
            key = floor(wrap360(ref[i]) * 100.0 + 0.5) / 100.0;
            for (g = 0u; g < distinct && keys[g] != key; ++g) {
            }
        }
        if (g < distinct) {
            replay_ref_group_t *q = &r->groups[g];
            q->n++;
            q->bias_deg += e;
            q->rms_deg += e * e;
            q->max_abs_deg = fmax(q->max_abs_deg, fabs(e));
        }
    }
    r->n_heading = n;
    if (n == 0u) {
        return;
    }
    r->heading_rms_deg = sqrt(s2 / (double)n);
    r->heading_bias_deg = s / (double)n;
    r->heading_max_abs_deg = mx;
    for (g = 0u; g < distinct; ++g) {
        replay_ref_group_t *q = &r->groups[g];
        if (q->n == 0u) {
            continue;
        }
        q->rms_deg = sqrt(q->rms_deg / (double)q->n);
        q->bias_deg /= (double)q->n;
        r->groups[r->n_groups++] = *q; /* compact: drop empty groups (g >= n_groups) */
    }
}

typedef struct {
    const char *path;
    const char *headings_path;
    int json;
    replay_options_t cal;
    const char *range;
    const char *plane_name;
    double declination;
    const char *mode;        /* "2d" | "3d" | "aided" */
    const char *ref_rows;    /* NULL = no swing */
    int fourier;             /* --swing-model fourier */
    int tilt;                /* -1 auto, 0 off, 1 on */
    int accel_unit;          /* 0 detect, 1 g, 2 m/s^2, 3 mg */
    double inclination;      /* NaN = not given */
    const char *field_unit;  /* --field-unit, NULL = not given (aided: uT) */
    double year;             /* NaN = from the dump */
    const char *prior_path;  /* aided: --prior, NULL = identity */
    const char *aided_objective; /* aided: --aided-objective, NULL = combined */
    const char *model;           /* aided: --model wmm2025 | igrf14, NULL = wmm2025 */
    const char *record_path;     /* --export-record FILE (replay_record.c), NULL = none */
    uint32_t sensor_id;          /* --sensor-id */
} cli_t;

/* Largest --eps accepted: the fits handle coordinates up to about 1e15 (ellipse.h). */
#define REPLAY_EPS_MAX 1e15

/* "A:B", "A:", ":B" with decimal row numbers (checked against the dump later). */
static int range_syntax_ok(const char *s)
{
    const char *colon = strchr(s, ':');
    size_t v;
    if (colon == NULL) {
        return 0;
    }
    if (colon > s && parse_size(s, (size_t)(colon - s), &v) != 0) {
        return 0;
    }
    return colon[1] == '\0' || parse_size(colon + 1, strlen(colon + 1), &v) == 0;
}

/* Long options (getopt_long: "--opt value" and "--opt=value"). Values >= 256 have no short form. */
enum {
    OPT_CAL_RANGE = 256, OPT_FILTER, OPT_EPS, OPT_MIN_PTS, OPT_DECLINATION, OPT_PLANE, OPT_HEADINGS,
    OPT_JSON, OPT_MODE, OPT_REF_ROWS, OPT_SWING_MODEL, OPT_TILT, OPT_NO_TILT, OPT_ACCEL_UNIT,
    OPT_INCLINATION, OPT_FIELD_UNIT, OPT_YEAR, OPT_MODEL, OPT_AIDED_OBJECTIVE, OPT_PRIOR,
    OPT_NO_CONSENSUS, OPT_FIT, OPT_EXPORT_RECORD, OPT_SENSOR_ID
};

static const struct option k_long_opts[] = {
    {"cal-range", required_argument, NULL, OPT_CAL_RANGE},
    {"filter", required_argument, NULL, OPT_FILTER},
    {"eps", required_argument, NULL, OPT_EPS},
    {"min-pts", required_argument, NULL, OPT_MIN_PTS},
    {"declination", required_argument, NULL, OPT_DECLINATION},
    {"plane", required_argument, NULL, OPT_PLANE},
    {"headings", required_argument, NULL, OPT_HEADINGS},
    {"json", no_argument, NULL, OPT_JSON},
    {"mode", required_argument, NULL, OPT_MODE},
    {"ref-rows", required_argument, NULL, OPT_REF_ROWS},
    {"swing-model", required_argument, NULL, OPT_SWING_MODEL},
    {"tilt", no_argument, NULL, OPT_TILT},
    {"no-tilt", no_argument, NULL, OPT_NO_TILT},
    {"accel-unit", required_argument, NULL, OPT_ACCEL_UNIT},
    {"inclination", required_argument, NULL, OPT_INCLINATION},
    {"field-unit", required_argument, NULL, OPT_FIELD_UNIT},
    {"year", required_argument, NULL, OPT_YEAR},
    {"model", required_argument, NULL, OPT_MODEL},
    {"aided-objective", required_argument, NULL, OPT_AIDED_OBJECTIVE},
    {"prior", required_argument, NULL, OPT_PRIOR},
    {"no-consensus", no_argument, NULL, OPT_NO_CONSENSUS},
    {"fit", required_argument, NULL, OPT_FIT},
    {"export-record", required_argument, NULL, OPT_EXPORT_RECORD},
    {"sensor-id", required_argument, NULL, OPT_SENSOR_ID},
    {"help", no_argument, NULL, 'h'},
    {NULL, 0, NULL, 0}};

static int one_of(const char *v, const char *const *names)
{
    size_t k;
    for (k = 0u; names[k] != NULL; ++k) {
        if (strcmp(v, names[k]) == 0) {
            return (int)k;
        }
    }
    return -1;
}

/* One option with its value (getopt_long has checked the name and the presence of a value). */
static int parse_opt(int opt, const char *v, cli_t *c)
{
    static const char *const k_filters[] = {"optics", "optics-classic", "dbscan", "none", NULL};
    static const char *const k_modes[] = {"2d", "3d", "aided", NULL};
    static const char *const k_accel[] = {"g", "mps2", "mg", NULL};
    static const char *const k_units[] = {"uT", "nT", "gauss", NULL};
    static const char *const k_models[] = {"wmm2025", "igrf14", NULL};
    static const char *const k_objectives[] = {"combined", "vector", NULL};
    static const char *const k_fits[] = {"consensus", "plain", NULL};
    size_t n;
    int k;
    switch (opt) {
    case OPT_JSON: c->json = 1; break;
    case OPT_TILT: c->tilt = 1; break;
    case OPT_NO_TILT: c->tilt = 0; break;
    case OPT_NO_CONSENSUS: c->cal.plain = 1; break;
    case OPT_FIT:
        if ((k = one_of(v, k_fits)) < 0) {
            return usage_error("--fit must be consensus or plain, got \"%s\"", v);
        }
        c->cal.plain = k;
        break;
    case OPT_CAL_RANGE:
        if (!range_syntax_ok(v)) {
            return usage_error("--cal-range must be A:B, A: or :B with row numbers, got \"%s\"", v);
        }
        c->range = v;
        break;
    case OPT_REF_ROWS:
        if (!range_syntax_ok(v)) {
            return usage_error("--ref-rows must be A:B, A: or :B with row numbers, got \"%s\"", v);
        }
        c->ref_rows = v;
        break;
    case OPT_FILTER:
        if (one_of(v, k_filters) < 0) {
            return usage_error("unknown filter \"%s\" (optics, optics-classic, dbscan, none)", v);
        }
        c->cal.filter = v;
        break;
    case OPT_EPS:
        if (parse_double(v, &c->cal.eps) != 0 || !(c->cal.eps > 0.0) || c->cal.eps > REPLAY_EPS_MAX) {
            return usage_error("--eps needs a positive number up to 1e15 (dump units), got \"%s\"", v);
        }
        break;
    case OPT_MIN_PTS:
        if (parse_size(v, strlen(v), &n) != 0 || n < 2u || n > (size_t)MAGCAL_MAX_MIN_PTS) {
            char m[96];
            (void)snprintf(m, sizeof m, "--min-pts needs an integer in 2..%u (MAGCAL_MAX_MIN_PTS), got \"%%s\"",
                           (unsigned)MAGCAL_MAX_MIN_PTS);
            return usage_error(m, v);
        }
        c->cal.min_pts = (long)n;
        break;
    case OPT_DECLINATION:
        if (parse_double(v, &c->declination) != 0 || fabs(c->declination) > 180.0) {
            return usage_error("--declination needs degrees in [-180, 180], got \"%s\"", v);
        }
        break;
    case OPT_PLANE:
        if (magcal_replay_csv_plane(v, &c->cal.plane) != MAGCAL_OK) {
            return usage_error("--plane must be XY, XZ or YZ (or YX, ZX, ZY), got \"%s\"", v);
        }
        c->plane_name = v;
        break;
    case OPT_HEADINGS: c->headings_path = v; break;
    case OPT_MODE:
        if (one_of(v, k_modes) < 0) {
            return usage_error("--mode must be 2d, 3d or aided, got \"%s\"", v);
        }
        c->mode = v;
        break;
    case OPT_SWING_MODEL:
        if (strcmp(v, "smith") != 0 && strcmp(v, "fourier") != 0) {
            return usage_error("--swing-model must be smith or fourier, got \"%s\"", v);
        }
        c->fourier = strcmp(v, "fourier") == 0;
        break;
    case OPT_ACCEL_UNIT:
        if ((k = one_of(v, k_accel)) < 0) {
            return usage_error("--accel-unit must be g, mg or mps2, got \"%s\"", v);
        }
        c->accel_unit = (k == 0) ? 1 : (k == 1) ? 2 : 3;
        break;
    case OPT_INCLINATION:
        if (parse_double(v, &c->inclination) != 0 || fabs(c->inclination) >= 90.0) {
            return usage_error("--inclination needs degrees in (-90, 90), got \"%s\"", v);
        }
        break;
    case OPT_FIELD_UNIT:
        if (one_of(v, k_units) < 0) {
            return usage_error("--field-unit must be uT, nT or gauss, got \"%s\"", v);
        }
        c->field_unit = v;
        break;
    case OPT_MODEL:
        if (one_of(v, k_models) < 0) {
            return usage_error("--model must be wmm2025 or igrf14, got \"%s\"", v);
        }
        c->model = v;
        break;
    case OPT_AIDED_OBJECTIVE:
        if (one_of(v, k_objectives) < 0) {
            return usage_error("--aided-objective must be combined or vector, got \"%s\"", v);
        }
        c->aided_objective = v;
        break;
    case OPT_PRIOR: c->prior_path = v; break;
    case OPT_EXPORT_RECORD: c->record_path = v; break; /* issue 15: replay_record.c */
    case OPT_SENSOR_ID:
        if (replay_parse_sensor_id(v, &c->sensor_id) != 0) {
            return usage_error("--sensor-id needs 0..0xFFFFFFFF, got \"%s\"", v);
        }
        break;
    case OPT_YEAR:
        if (parse_double(v, &c->year) != 0 || c->year < 1900.0 || c->year > 2100.0) {
            return usage_error("--year needs a decimal year in [1900, 2100], got \"%s\"", v);
        }
        break;
    default:
        return usage_error("%s", "internal: unhandled option");
    }
    return -1;
}

static int parse_args(int argc, char **argv, cli_t *c)
{
    int opt, rc;
    memset(c, 0, sizeof *c);
    c->cal.filter = "optics";
    c->cal.eps = NAN;
    c->cal.min_pts = 0;
    c->plane_name = "XY";
    (void)magcal_replay_csv_plane("XY", &c->cal.plane);
    c->mode = "2d";
    c->tilt = -1;
    c->inclination = NAN;
    c->year = NAN;
    opterr = 0; /* our own messages */
    optind = 1;
    while ((opt = getopt_long(argc, argv, ":h", k_long_opts, NULL)) != -1) {
        const char *a = argv[optind - 1];
        if (opt == 'h') {
            fputs(k_usage, stdout);
            exit(REPLAY_EXIT_OK);
        }
        if (opt == ':') {
            return usage_error("option %s needs a value", a);
        }
        if (opt == '?') {
            if (optopt != 0 && optopt < 256) {
                char s[3] = {'-', (char)optopt, '\0'};
                return usage_error("unknown option %s", s);
            }
            if (optopt >= 256) { /* a known long option that takes no value, given one */
                return usage_error("option %s takes no value", a);
            }
            return usage_error("unknown (or ambiguous) option %s", a);
        }
        rc = parse_opt(opt, optarg, c);
        if (rc >= 0) {
            return rc;
        }
    }
    for (; optind < argc; ++optind) {
        if (c->path != NULL) {
            return usage_error("more than one dump given (%s)", argv[optind]);
        }
        c->path = argv[optind];
    }
    if (c->path == NULL) {
        return usage_error("%s", "no dump file given");
    }
    if (strcmp(c->cal.filter, "none") == 0 && (isfinite(c->cal.eps) || c->cal.min_pts > 0)) {
        return usage_error("%s", "--eps/--min-pts make no sense with --filter none");
    }
    if (c->cal.plain && (strcmp(c->cal.filter, "optics") != 0 || isfinite(c->cal.eps) || c->cal.min_pts > 0)) {
        return usage_error("%s", "--no-consensus (--fit plain) is the unfiltered least-squares fit: no --filter, "
                                 "--eps or --min-pts");
    }
    if (c->cal.plain && strcmp(c->mode, "2d") != 0) {
        return usage_error("%s", "--no-consensus (--fit plain) is for the 2d mode (3d: --filter none skips the "
                                 "density stage; the ellipsoid fit's gate stays)");
    }
    if (strcmp(c->mode, "aided") == 0 && c->tilt == 1) {
        return usage_error("%s", "--tilt: the aided mode levels the field with the INS roll and pitch");
    }
    if (c->prior_path != NULL && strcmp(c->mode, "aided") != 0) {
        return usage_error("%s", "--prior is for the aided mode (the prior of magcal_aided_update)");
    }
    if (strcmp(c->mode, "3d") == 0 && strcmp(c->cal.filter, "dbscan") == 0) {
        return usage_error("%s", "--filter dbscan is 2-D only (3d: optics, optics-classic or none)");
    }
    if (c->model != NULL && strcmp(c->mode, "aided") != 0) {
        return usage_error("%s", "--model is for the aided mode (the reference field of magcal_aided_update)");
    }
    if (c->aided_objective != NULL && strcmp(c->mode, "aided") != 0) {
        return usage_error("%s", "--aided-objective is for the aided mode");
    }
    if (isfinite(c->inclination) && strcmp(c->mode, "2d") != 0) {
        return usage_error("%s", "--inclination is for the 2d mode (3d and aided calibrate z)");
    }
    return -1; /* continue */
}

/* Parse "A:B", "A:", ":B" against n rows. 0 ok, -1 bad. */
static int parse_range(const char *opt, const char *s, size_t n, size_t *a, size_t *b, char *msg,
                       size_t msg_len)
{
    const char *colon = strchr(s, ':');
    if (colon == NULL) {
        (void)snprintf(msg, msg_len, "%s must be A:B, got \"%s\"", opt, s);
        return -1;
    }
    *a = 0u;
    *b = n;
    if ((colon > s && parse_size(s, (size_t)(colon - s), a) != 0) ||
        (colon[1] != '\0' && parse_size(colon + 1, strlen(colon + 1), b) != 0)) {
        (void)snprintf(msg, msg_len, "%s must be A:B with row numbers, got \"%s\"", opt, s);
        return -1;
    }
    if (*a >= *b || *b > n) {
        (void)snprintf(msg, msg_len, "%s %s is empty or beyond the dump's %lu rows", opt, s,
                       (unsigned long)n);
        return -1;
    }
    return 0;
}

/* Median of |a| over the rows with a finite accelerometer sample (NaN when none). */
static double median_accel_norm(const magcal_replay_csv_t *d)
{
    const double *ax = d->col[MAGCAL_REPLAY_COL_AX], *ay = d->col[MAGCAL_REPLAY_COL_AY];
    const double *az = d->col[MAGCAL_REPLAY_COL_AZ];
    double *v = (double *)malloc(d->n_rows * sizeof(double)), med;
    size_t i, k = 0u, g;
    if (v == NULL) {
        return NAN;
    }
    for (i = 0u; i < d->n_rows; ++i) {
        if (isfinite(ax[i]) && isfinite(ay[i]) && isfinite(az[i])) {
            v[k++] = sqrt(ax[i] * ax[i] + ay[i] * ay[i] + az[i] * az[i]);
        }
    }
    /* selection by partial sorting is not worth it here: a shell sort of k values */
    for (g = k / 2u; g > 0u; g /= 2u) {
        for (i = g; i < k; ++i) {
            double t = v[i];
            size_t j = i;
            while (j >= g && v[j - g] > t) {
                v[j] = v[j - g];
                j -= g;
            }
            v[j] = t;
        }
    }
    med = (k == 0u) ? NAN : (k % 2u) ? v[k / 2u] : 0.5 * (v[k / 2u - 1u] + v[k / 2u]);
    free(v);
    return med;
}

static int tilt_slot(magcal_status_t st)
{
    switch (st) {
    case MAGCAL_OK: return REPLAY_TILT_OK;
    case MAGCAL_ERR_FREE_FALL: return REPLAY_TILT_FREE_FALL;
    case MAGCAL_ERR_ACCEL_NORM: return REPLAY_TILT_ACCEL_NORM;
    case MAGCAL_ERR_GIMBAL: return REPLAY_TILT_GIMBAL;
    case MAGCAL_ERR_ZERO_FIELD: return REPLAY_TILT_ZERO_FIELD;
    default: return REPLAY_TILT_NO_ACCEL;
    }
}

int main(int argc, char **argv)
{
    cli_t c;
    magcal_replay_csv_t d;
    replay_report_t r;
    replay_result_t res;
    replay_swing_t sw;
    magcal_ellipsoid_cal_t cal3;
    magcal_ellipsoid_result_t fit3;
    char err[MAGCAL_REPLAY_CSV_ERR_LEN];
    uint32_t required;
    int rc, mode3d, aided, vehicle = 0;
    size_t i, n;
    magcal_vec3_t *fed = NULL;
    double *raw_rad = NULL, *cor_rad = NULL, *err_deg = NULL, *hdg = NULL, *raw_hdg = NULL;
    double *hmag = NULL, *hmag0 = NULL, *decl = NULL, *bned = NULL, *refmag = NULL;
    unsigned char *flag = NULL, *use = NULL, *fedmask = NULL, *tstat = NULL, *gate_row = NULL;
    const double *ref;
    double accel_scale = 1.0;
    static const double k_nan = NAN;

    if (replay_stream_requested(argc, argv)) {
        return replay_stream_main(argc, argv);
    }
    rc = parse_args(argc, argv, &c);
    if (rc >= 0) {
        return rc;
    }
    mode3d = strcmp(c.mode, "3d") == 0;
    aided = strcmp(c.mode, "aided") == 0;
    memset(&d, 0, sizeof d);
    memset(&r, 0, sizeof r);
    memset(&res, 0, sizeof res);
    memset(&sw, 0, sizeof sw);
    memset(&cal3, 0, sizeof cal3);
    memset(&fit3, 0, sizeof fit3);
    required = MAGCAL_REPLAY_COL_BIT(MAGCAL_REPLAY_COL_MX + c.cal.plane.src[0]) |
               MAGCAL_REPLAY_COL_BIT(MAGCAL_REPLAY_COL_MX + c.cal.plane.src[1]);
    if (mode3d || aided) {
        required |= MAGCAL_REPLAY_COL_BIT(MAGCAL_REPLAY_COL_MX + c.cal.plane.src[2]);
    }
    if (aided) {
        required |= MAGCAL_REPLAY_COL_BIT(MAGCAL_REPLAY_COL_ROLL) | MAGCAL_REPLAY_COL_BIT(MAGCAL_REPLAY_COL_PITCH) |
                    MAGCAL_REPLAY_COL_BIT(MAGCAL_REPLAY_COL_YAW) | MAGCAL_REPLAY_COL_BIT(MAGCAL_REPLAY_COL_LAT) |
                    MAGCAL_REPLAY_COL_BIT(MAGCAL_REPLAY_COL_LON) | MAGCAL_REPLAY_COL_BIT(MAGCAL_REPLAY_COL_HEIGHT);
    }
    if (c.tilt == 1) {
        required |= MAGCAL_REPLAY_COL_BIT(MAGCAL_REPLAY_COL_MX + c.cal.plane.src[2]);
    }
    if (magcal_replay_csv_read(c.path, required, &d, err, sizeof err) != MAGCAL_OK) {
        fprintf(stderr, "magcal-replay: %s\n", err);
        return REPLAY_EXIT_INPUT;
    }
    n = d.n_rows;
    if (aided && c.field_unit == NULL) {
        c.field_unit = "uT"; /* the aided mode compares with the WMM field: it needs a unit */
    }
    r.mode = c.mode;
    r.file = c.path;
    r.filter = c.cal.plain ? "none" : c.cal.filter;
    r.fit = c.cal.plain ? "plain" : "consensus";
    r.unit = c.field_unit;
    r.sep = d.sep;
    r.est_heading_err_deg = NAN;
    r.missing_start_deg = NAN;
    r.missing_width_deg = NAN;
    replay_check_columns(&d, &r.warnings);
    replay_check_ref_units(&d, &r.warnings);
    if (aided) {
        replay_check_ins_angles(&d, &r.warnings);
    }
    r.plane = c.plane_name;
    r.declination_deg = c.declination;
    r.eps = c.cal.eps;
    r.min_pts = c.cal.min_pts;
    r.n_rows = n;
    r.cal_first = 0u;
    r.cal_end = n;
    r.inclination_deg = c.inclination;
    r.converged_at = -1;
    r.converged_row = -1;
    if (c.range != NULL &&
        parse_range("--cal-range", c.range, n, &r.cal_first, &r.cal_end, err, sizeof err) != 0) {
        fprintf(stderr, "magcal-replay: %s\n", err);
        magcal_replay_csv_free(&d);
        return REPLAY_EXIT_INPUT;
    }
    r.n_cal = r.cal_end - r.cal_first;
    if (c.ref_rows != NULL) {
        if (parse_range("--ref-rows", c.ref_rows, n, &r.ref_first, &r.ref_end, err, sizeof err) != 0) {
            fprintf(stderr, "magcal-replay: %s\n", err);
            magcal_replay_csv_free(&d);
            return REPLAY_EXIT_INPUT;
        }
        if (d.col[MAGCAL_REPLAY_COL_HEADING_REF] == NULL) {
            fprintf(stderr, "magcal-replay: %s: --ref-rows needs a heading_ref_deg column\n", c.path);
            magcal_replay_csv_free(&d);
            return REPLAY_EXIT_INPUT;
        }
        r.swing_requested = 1;
    }

    /* Tilt compensation: auto-on when ax, ay, az and the third field axis are present. */
    {
        int have_acc = d.col[MAGCAL_REPLAY_COL_AX] != NULL && d.col[MAGCAL_REPLAY_COL_AY] != NULL &&
                       d.col[MAGCAL_REPLAY_COL_AZ] != NULL;
        int have_z = d.col[MAGCAL_REPLAY_COL_MX + c.cal.plane.src[2]] != NULL;
        if (c.tilt == 1 && !have_acc) {
            fprintf(stderr, "magcal-replay: %s: --tilt needs the columns ax, ay, az\n", c.path);
            magcal_replay_csv_free(&d);
            return REPLAY_EXIT_INPUT;
        }
        r.tilt_on = !aided && c.tilt != 0 && have_acc && have_z;
        if (!aided && have_acc) {
            double share = 0.0, excess = NAN;
            vehicle = replay_check_vehicle(&d, &c.cal.plane, &share, &excess);
            if (vehicle && r.tilt_on && !mode3d && c.tilt == -1) {
                r.tilt_on = 0;
                replay_warn(&r.warnings, "centripetal",
                            "tilt compensation is off: the accelerometer sees centripetal acceleration (%.0f %% "
                            "of the rows have a horizontal acceleration above 0.15 g with |a| rising %.2f x as "
                            "on a level road: a turning vehicle), which 2-D tilt compensation would read as tilt "
                            "(--inclination makes that worse). Give --tilt to force it; --mode aided levels "
                            "with INS attitude instead",
                            100.0 * share, excess);
            } else if (vehicle && r.tilt_on) {
                replay_warn(&r.warnings, "centripetal",
                            "the accelerometer sees centripetal acceleration (%.0f %% of the rows, |a| rising "
                            "%.2f x as on a level road: a turning vehicle): tilt compensation reads it as tilt "
                            "and the heading error grows in turns; consider --no-tilt",
                            100.0 * share, excess);
            }
        }
    }
    if (r.tilt_on) {
        r.accel_median_norm = median_accel_norm(&d);
        if (c.accel_unit != 0) {
            r.accel_unit = (c.accel_unit == 1) ? "g" : (c.accel_unit == 2) ? "mps2" : "mg";
            r.accel_unit_source = "given";
        } else if (r.accel_median_norm >= 0.5 && r.accel_median_norm <= 2.0) {
            r.accel_unit = "g";
            r.accel_unit_source = "detected";
        } else if (r.accel_median_norm >= 4.9 && r.accel_median_norm <= 19.6) {
            r.accel_unit = "mps2";
            r.accel_unit_source = "detected";
        } else if (r.accel_median_norm >= 500.0 && r.accel_median_norm <= 2000.0) {
            r.accel_unit = "mg";
            r.accel_unit_source = "detected";
        } else {
            fprintf(stderr,
                    "magcal-replay: %s: cannot tell the accelerometer unit (median |a| = %g; about 1 "
                    "means g, about 9.8 m/s^2, about 1000 mg; raw counts must be converted first): give "
                    "--accel-unit g|mg|mps2 or --no-tilt\n",
                    c.path, r.accel_median_norm);
            magcal_replay_csv_free(&d);
            return REPLAY_EXIT_INPUT;
        }
        accel_scale = (strcmp(r.accel_unit, "g") == 0)    ? 1.0
                      : (strcmp(r.accel_unit, "mg") == 0) ? 1e-3
                                                          : 1.0 / 9.80665;
        replay_check_accel_down(&d, &c.cal.plane, &r.warnings);
    }

    /* Decimation (2d): the calibrator holds at most `capacity` samples; feed every k-th row.
     * The 3-D fit and the aided estimator take every calibration row. */
    r.capacity = (mode3d || aided) ? r.n_cal : replay_capacity();
    r.decimation = (r.n_cal + r.capacity - 1u) / r.capacity;
    if (r.decimation < 1u) {
        r.decimation = 1u;
    }
    r.n_fed = (r.n_cal + r.decimation - 1u) / r.decimation;

    fed = (magcal_vec3_t *)calloc(n, sizeof *fed);
    raw_rad = (double *)calloc(n, sizeof(double));
    cor_rad = (double *)calloc(n, sizeof(double));
    err_deg = (double *)calloc(n, sizeof(double));
    hdg = (double *)calloc(n, sizeof(double));
    raw_hdg = (double *)calloc(n, sizeof(double));
    hmag = (double *)calloc(n, sizeof(double));
    hmag0 = (double *)calloc(n, sizeof(double));
    decl = (double *)calloc(n, sizeof(double));
    refmag = (double *)calloc(n, sizeof(double));
    bned = (double *)calloc(3u * n, sizeof(double));
    flag = (unsigned char *)calloc(n, 1u);
    use = (unsigned char *)calloc(n, 1u);
    fedmask = (unsigned char *)calloc(n, 1u);
    tstat = (unsigned char *)calloc(n, 1u);
    gate_row = (unsigned char *)calloc(n, 1u);
    res.flags = (unsigned char *)calloc(r.n_fed, 1u);
    if (!fed || !raw_rad || !cor_rad || !err_deg || !hdg || !raw_hdg || !hmag || !hmag0 || !decl || !refmag ||
        !bned || !flag || !use || !fedmask || !tstat || !gate_row || !res.flags) {
        fprintf(stderr, "magcal-replay: out of memory\n");
        rc = REPLAY_EXIT_INTERNAL;
        goto done;
    }
    /* every row mapped into the library frame (in-plane axes are required: always finite) */
    if (magcal_replay_csv_fill(&d, 0u, n, 1u, &c.cal.plane, fed, NULL, NULL) != MAGCAL_OK) {
        fprintf(stderr, "magcal-replay: %s: internal error mapping rows\n", c.path);
        rc = REPLAY_EXIT_INTERNAL;
        goto done;
    }
    for (i = 0u; i < n; ++i) {
        decl[i] = c.declination;
    }
    replay_check_eps(fed + r.cal_first, r.n_cal, mode3d, c.cal.eps, r.unit, &r.warnings);

    /* Calibrate. */
    if (aided) {
        replay_aided_opts_t ao;
        magcal_ellipsoid_cal_t prior;
        char perr[512];
        ao.unit_per_nt = (strcmp(c.field_unit, "nT") == 0) ? 1.0 : (strcmp(c.field_unit, "gauss") == 0) ? 1e-5 : 1e-3;
        ao.year = c.year;
        ao.igrf = (c.model != NULL && strcmp(c.model, "igrf14") == 0);
        r.geomag_model = ao.igrf ? "IGRF-14" : "WMM2025";
        r.field_unit = c.field_unit;
        r.prior = (c.prior_path != NULL) ? c.prior_path : "identity";
        r.aided_objective = (c.aided_objective != NULL) ? c.aided_objective : "combined";
        rc = replay_wmm_rows(&d, &ao, bned, decl, err, sizeof err);
        if (rc != REPLAY_EXIT_OK) {
            fprintf(stderr, "magcal-replay: %s: %s\n", c.path, err);
            goto done;
        }
        replay_check_field_wmm(fed, bned, r.cal_first, r.cal_end, ao.unit_per_nt, c.field_unit, r.geomag_model,
                               &r.warnings);
        r.prior_g_scale = 1.0;
        if (c.prior_path != NULL) {
            double fref = NAN; /* |B_ref| of the first calibration row that has one */
            for (i = r.cal_first; i < r.cal_end && !isfinite(fref); ++i) {
                if (isfinite(bned[3u * i])) {
                    fref = sqrt(bned[3u * i] * bned[3u * i] + bned[3u * i + 1u] * bned[3u * i + 1u] +
                                bned[3u * i + 2u] * bned[3u * i + 2u]);
                }
            }
            rc = replay_read_prior(c.prior_path, ao.unit_per_nt, fref, &prior, &r.prior_g_scale, perr, sizeof perr);
            if (rc != REPLAY_EXIT_OK) {
                fprintf(stderr, "magcal-replay: %s\n", perr);
                goto done;
            }
        }
        rc = replay_aided_run(&d, fed, bned, r.cal_first, r.cal_end, c.prior_path != NULL ? &prior : NULL, &r, &cal3,
                              gate_row);
        if (rc == REPLAY_EXIT_INPUT) {
            fprintf(stderr, "magcal-replay: %s: prior refused by magcal_aided_init: %s\n", c.prior_path, r.reason);
            goto done;
        }
        r.decl_first_deg = NAN;
        for (i = r.cal_first; i < r.cal_end; ++i) {
            if (isfinite(decl[i])) {
                r.decl_first_deg = decl[i];
                break;
            }
        }
    } else if (mode3d) {
        rc = replay_fit_3d(fed + r.cal_first, r.n_cal, c.cal.filter, c.cal.eps, c.cal.min_pts, &r, &fit3,
                           flag + r.cal_first);
        if (rc == REPLAY_EXIT_OK) {
            cal3 = fit3.cal;
        }
    } else {
        /* Replay port serves the (decimated) calibration rows; the calibrator polls. */
        rc = replay_calibrate(&c.cal, &d, r.cal_first, r.n_fed, r.decimation, &r, &res);
    }
    if (rc != REPLAY_EXIT_OK && rc != REPLAY_EXIT_CAL_FAILED) {
        goto done;
    }
    for (i = r.cal_first; i < r.cal_end; i += r.decimation) {
        fedmask[i] = 1u;
    }

    /* 2d + tilt: the vertical component (approximation, docs/replay.md "Tilt compensation"). */
    if (rc == REPLAY_EXIT_OK && r.tilt_on && !mode3d && !aided) {
        double sz = 0.0;
        size_t kz = 0u;
        for (i = r.cal_first; i < r.cal_end; i += r.decimation) {
            size_t k = (i - r.cal_first) / r.decimation;
            if (!res.flags[k] && d.col[MAGCAL_REPLAY_COL_MX + c.cal.plane.src[2]] != NULL &&
                isfinite(d.col[MAGCAL_REPLAY_COL_MX + c.cal.plane.src[2]][i])) {
                sz += fed[i].z;
                kz++;
            }
        }
        r.tilt_z_offset = (kz > 0u) ? sz / (double)kz : 0.0;
        r.tilt_hz_level = isfinite(c.inclination) ? -(double)res.cal.radius * tan(c.inclination * 3.14159265358979323846 / 180.0) : 0.0;
        r.tilt_field = "2d: h = (M (raw_xy - centre), mz - z_offset + hz_level)";
        if (!isfinite(c.inclination) && !vehicle) {
            fprintf(stderr, "magcal-replay: note: 2d tilt compensation without --inclination takes the "
                            "level vertical field as 0, which leaves most of the tilt error (docs/replay.md, "
                            "\"Tilt compensation\"); give --inclination, use --mode 3d, or --no-tilt\n");
        }
    } else if (r.tilt_on) {
        r.tilt_field = "3d: h = G (m - V)";
    }

    /* Per-row headings and flags. */
    ref = d.col[MAGCAL_REPLAY_COL_HEADING_REF];
    for (i = 0u; i < n; ++i) {
        magcal_vec2_t raw = {fed[i].x, fed[i].y};
        magcal_vec3_t h3 = {0.0f, 0.0f, 0.0f};
        int have_h3 = 0;
        raw_rad[i] = sqrt((double)raw.x * raw.x + (double)raw.y * raw.y);
        if (mode3d || aided) {
            raw_rad[i] = sqrt((double)fed[i].x * fed[i].x + (double)fed[i].y * fed[i].y + (double)fed[i].z * fed[i].z);
        }
        raw_hdg[i] = (raw.x != 0.0f || raw.y != 0.0f)
                         ? wrap360(atan2(-(double)raw.x, (double)raw.y) * k_deg_per_rad + c.declination)
                         : NAN;
        hdg[i] = NAN;
        hmag[i] = NAN;
        err_deg[i] = NAN;
        cor_rad[i] = NAN;
        refmag[i] = (ref != NULL && isfinite(ref[i]) && isfinite(decl[i])) ? ref[i] - decl[i] : NAN;
        if (rc != REPLAY_EXIT_OK) {
            continue;
        }
        if (!mode3d && !aided) {
            magcal_vec2_t h;
            float mag_deg = 0.0f, true_deg = 0.0f;
            if (magcal_correct_apply(&res.cal, raw, &h) == MAGCAL_OK) {
                cor_rad[i] = sqrt((double)h.x * h.x + (double)h.y * h.y);
                h3.x = h.x;
                h3.y = h.y;
                h3.z = (float)((double)fed[i].z - r.tilt_z_offset + r.tilt_hz_level);
                have_h3 = 1;
            }
            if (!r.tilt_on && magcal_heading_compute(&res.cal, raw, (float)c.declination, &mag_deg, &true_deg) ==
                                  MAGCAL_OK) {
                hdg[i] = true_deg;
                hmag[i] = mag_deg;
            }
            if (i >= r.cal_first && i < r.cal_end && (i - r.cal_first) % r.decimation == 0u) {
                size_t k = (i - r.cal_first) / r.decimation;
                flag[i] = res.flags[k];
                use[i] = (unsigned char)!res.flags[k];
            } else {
                flag[i] = (unsigned char)replay_classify(&res, raw);
            }
        } else {
            if (magcal_ellipsoid_apply(&cal3, &fed[i], &h3) == MAGCAL_OK) {
                have_h3 = 1;
                cor_rad[i] = sqrt((double)h3.x * h3.x + (double)h3.y * h3.y + (double)h3.z * h3.z);
            }
            use[i] = fedmask[i];
            if (aided) {
                /* rejected by a gate of magcal_aided_update (gate_row: none, or not offered) */
                flag[i] = (unsigned char)(gate_row[i] >= MAGCAL_AIDED_GATE_DOP && gate_row[i] < MAGCAL_AIDED_GATE_COUNT);
            } else if (i < r.cal_first || i >= r.cal_end) {
                /* calibration rows: the fit's own mask; others: the same final gate */
                flag[i] = (unsigned char)replay_classify_3d(&fit3, &fed[i]);
            }
            r.n_outlier_rows += (size_t)(flag[i] != 0u);
            if (have_h3 && aided) {
                const double *ro = d.col[MAGCAL_REPLAY_COL_ROLL], *pi = d.col[MAGCAL_REPLAY_COL_PITCH];
                magcal_tilt_t att;
                magcal_vec3_t lv;
                float psi = 0.0f;
                att.roll_deg = (float)ro[i];
                att.pitch_deg = (float)pi[i];
                if (isfinite(ro[i]) && isfinite(pi[i]) && magcal_tilt_level_field(&att, &h3, &lv) == MAGCAL_OK) {
                    magcal_vec2_t l2 = {lv.x, lv.y};
                    if (magcal_heading_from_field(l2, &psi) == MAGCAL_OK) {
                        hmag[i] = psi;
                    }
                }
            } else if (have_h3 && !r.tilt_on) {
                magcal_vec2_t l2 = {h3.x, h3.y};
                float psi = 0.0f;
                if (magcal_heading_from_field(l2, &psi) == MAGCAL_OK) {
                    hmag[i] = psi; /* level assumption */
                }
            }
        }
        if (r.tilt_on) {
            const magcal_tilt_cfg_t tcfg = MAGCAL_TILT_CFG_DEFAULT;
            magcal_status_t st = MAGCAL_ERR_NONFINITE;
            double a[3];
            unsigned k;
            int fin = have_h3;
            for (k = 0u; k < 3u; ++k) {
                a[k] = d.col[MAGCAL_REPLAY_COL_AX + c.cal.plane.src[k]][i] * accel_scale;
                fin = fin && isfinite(a[k]);
            }
            if (fin) {
                magcal_vec3_t acc = {(float)a[0], (float)a[1], (float)a[2]};
                float psi = 0.0f;
                st = magcal_tilt_heading(&tcfg, &acc, &h3, &psi, NULL);
                if (st == MAGCAL_OK) {
                    hmag[i] = psi;
                }
            }
            tstat[i] = (unsigned char)tilt_slot(st);
            r.tilt_counts[tstat[i]]++;
        }
        if (isfinite(hmag[i]) && !isfinite(hdg[i])) {
            hdg[i] = wrap360(hmag[i] + decl[i]);
        }
        if (ref != NULL && isfinite(ref[i]) && isfinite(hdg[i])) {
            err_deg[i] = wrap180(hdg[i] - ref[i]);
        }
    }
    if (rc == REPLAY_EXIT_OK) {
        /* raw spread over the samples used (same set as the corrected one), and over every
         * fed calibration sample (outliers included) */
        r.spread_raw = spread(raw_rad, use, n);
        r.spread_raw_all = spread(raw_rad, fedmask, n);
        r.spread_corrected = spread(cor_rad, use, n);
        heading_metrics(&r, ref != NULL ? ref : &k_nan, err_deg, flag, ref != NULL ? n : 0u);
        if (!aided) {
            replay_check_field_range(mode3d ? r.field3 : r.radius, !mode3d, r.unit, &r.warnings);
        }
        if (!aided && r.n_heading > 0u) {
            double ratio = (mode3d ? r.spread_raw_all : r.spread_raw) / fmax(r.spread_corrected, 1e-12);
            replay_check_heading_pattern(hdg, ref, n, &r, ratio, &r.warnings);
        }
        /* Compass swing on the reference rows, on the calibrated magnetic heading. */
        if (r.swing_requested) {
            rc = replay_swing_fit(hmag, refmag, r.ref_first, r.ref_end, c.fourier, &r, &sw);
            if (rc != REPLAY_EXIT_OK) {
                goto done;
            }
            r.n_heading_before = r.n_heading;
            r.rms_before = r.heading_rms_deg;
            r.bias_before = r.heading_bias_deg;
            r.max_before = r.heading_max_abs_deg;
            if (sw.ok) {
                for (i = 0u; i < n; ++i) {
                    hmag0[i] = hmag[i];
                    hmag[i] = replay_swing_apply(&sw, hmag[i]);
                    hdg[i] = isfinite(hmag[i]) ? wrap360(hmag[i] + decl[i]) : NAN;
                    err_deg[i] = (ref != NULL && isfinite(ref[i]) && isfinite(hdg[i])) ? wrap180(hdg[i] - ref[i]) : NAN;
                }
                heading_metrics(&r, ref != NULL ? ref : &k_nan, err_deg, flag, ref != NULL ? n : 0u);
            }
        }
    }
    if (!mode3d && !aided) {
        replay_check_level(&d, fed, &c.cal.plane, vehicle, &r, &r.warnings);
    }
    /* truth flags of the dump (glitch on recorded dumps, outlier on synthetic ones) */
    {
        const double *truth = d.col[MAGCAL_REPLAY_COL_GLITCH];
        r.truth_column = "glitch";
        if (truth == NULL) {
            truth = d.col[MAGCAL_REPLAY_COL_OUTLIER];
            r.truth_column = "outlier";
        }
        if (truth == NULL || rc != REPLAY_EXIT_OK || aided) {
            r.truth_column = NULL;
        } else {
            for (i = r.cal_first; i < r.cal_end; i += r.decimation) {
                int t = isfinite(truth[i]) && truth[i] != 0.0;
                r.truth_flagged += (size_t)t;
                r.truth_detected += (size_t)(t && flag[i]);
                r.truth_missed += (size_t)(t && !flag[i]);
                r.false_alarms += (size_t)(!t && flag[i]);
            }
        }
    }

    if (c.headings_path != NULL && rc == REPLAY_EXIT_OK) {
        static const char *const k_tilt_names[REPLAY_TILT_COUNT] = {"ok", "free_fall", "accel_norm",
                                                                   "gimbal", "zero_field", "no_accel"};
        FILE *f = fopen(c.headings_path, "w");
        int bad = (f == NULL);
        if (f != NULL) {
            fprintf(f, "index,raw_heading_deg,heading_deg,outlier%s%s%s%s\n",
                    ref != NULL ? ",heading_ref_deg,error_deg" : "", r.tilt_on ? ",tilt" : "",
                    sw.ok ? ",heading_before_swing_deg" : "", aided ? ",gate" : "");
            for (i = 0u; i < n; ++i) {
                fprintf(f, "%lu,%.4f,%.4f,%d", (unsigned long)i, raw_hdg[i], hdg[i], flag[i]);
                if (ref != NULL) {
                    fprintf(f, ",%.4f,%.4f", ref[i], err_deg[i]);
                }
                if (r.tilt_on) {
                    fprintf(f, ",%s", k_tilt_names[tstat[i]]);
                }
                if (sw.ok) {
                    fprintf(f, ",%.4f", isfinite(hmag0[i]) ? wrap360(hmag0[i] + decl[i]) : NAN);
                }
                if (aided) {
                    fprintf(f, ",%s", replay_gate_name(gate_row[i]));
                }
                fputc('\n', f);
            }
            bad = ferror(f) != 0;
            bad |= fclose(f) != 0;
        }
        if (bad) {
            fprintf(stderr, "magcal-replay: %s: cannot write: %s\n", c.headings_path, strerror(errno));
            rc = REPLAY_EXIT_OUTPUT;
            goto done;
        }
    }

    if (c.json) {
        if (replay_print_json(&r) != 0) {
            fprintf(stderr, "magcal-replay: cannot write the JSON report\n");
            rc = REPLAY_EXIT_OUTPUT;
        }
    } else {
        replay_print_table(&r);
    }
    if (rc == REPLAY_EXIT_CAL_FAILED) {
        fprintf(stderr, "magcal-replay: %s: calibration failed: %s: %s\n", c.path, r.status, r.reason);
    } else if (c.record_path != NULL && rc == REPLAY_EXIT_OK) { /* issue 15: replay_record.c */
        rc = replay_export_record(c.record_path, &r, &res.cal, &cal3, c.sensor_id, err, sizeof err);
        if (rc != REPLAY_EXIT_OK) {
            fprintf(stderr, "magcal-replay: %s\n", err);
        }
    }
    if (fflush(stdout) != 0 && rc == REPLAY_EXIT_OK) {
        rc = REPLAY_EXIT_OUTPUT;
    }

done:
    free(fed);
    free(raw_rad);
    free(cor_rad);
    free(err_deg);
    free(hdg);
    free(raw_hdg);
    free(hmag);
    free(hmag0);
    free(decl);
    free(refmag);
    free(bned);
    free(flag);
    free(use);
    free(fedmask);
    free(tstat);
    free(gate_row);
    free(res.flags);
    magcal_replay_csv_free(&d);
    return rc;
}
