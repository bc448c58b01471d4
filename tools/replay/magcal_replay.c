/*
 * magcal-replay: replay a recorded (or generated) magnetometer dump through the magcal library,
 * over the same code path the MCU runs (replay port -> magcal_calibrator_poll -> run), and report
 * the calibration and its heading accuracy. Usage and every output field: docs/replay.md.
 */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "magcal/calibrator.h"
#include "magcal/heading.h"
#include "magcal/status.h"
#include "magcal_port_replay.h"
#include "replay_cal.h"
#include "replay_csv.h"
#include "replay_report.h"

static const char k_usage[] =
    "usage: magcal-replay [options] DUMP.csv\n"
    "  --cal-range A:B     rows [A,B) are the calibration segment (default: all rows;\n"
    "                      A: or :B leave one end open)\n"
    "  --filter MODE       optics (default, automatic parameters) | optics-classic | dbscan | none\n"
    "  --eps F             override the automatic OPTICS/DBSCAN radius (dump units)\n"
    "  --min-pts N         override the automatic MinPts\n"
    "  --declination DEG   magnetic declination, east positive (default 0)\n"
    "  --plane XY|XZ|YZ    dump axes forming the horizontal plane (default XY; YX, ZX, ZY mirror)\n"
    "  --headings OUT.csv  per row: index,raw_heading_deg,heading_deg,outlier[,heading_ref_deg,error_deg]\n"
    "  --json              the report as one JSON object on stdout (default: a readable table)\n"
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
    /* distinct reference values (to 0.01 deg); too many -> 45-degree sectors */
    for (i = 0u; i < n_rows; ++i) {
        double key;
        if ((i >= r->cal_first && i < r->cal_end) || !isfinite(ref[i]) || !isfinite(err[i])) {
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
        if ((i >= r->cal_first && i < r->cal_end) || !isfinite(ref[i]) || !isfinite(err[i])) {
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
} cli_t;

static int parse_args(int argc, char **argv, cli_t *c)
{
    int i;
    memset(c, 0, sizeof *c);
    c->cal.filter = "optics";
    c->cal.eps = NAN;
    c->cal.min_pts = 0;
    c->plane_name = "XY";
    for (i = 1; i < argc; ++i) {
        const char *a = argv[i];
        const char *v = (i + 1 < argc) ? argv[i + 1] : NULL;
        if (strcmp(a, "-h") == 0 || strcmp(a, "--help") == 0) {
            fputs(k_usage, stdout);
            exit(REPLAY_EXIT_OK);
        } else if (strcmp(a, "--json") == 0) {
            c->json = 1;
        } else if (a[0] == '-' && a[1] == '-' && v == NULL) {
            return usage_error("option %s needs a value", a);
        } else if (strcmp(a, "--cal-range") == 0) {
            c->range = v;
            ++i;
        } else if (strcmp(a, "--filter") == 0) {
            if (strcmp(v, "optics") != 0 && strcmp(v, "optics-classic") != 0 &&
                strcmp(v, "dbscan") != 0 && strcmp(v, "none") != 0) {
                return usage_error("unknown filter \"%s\" (optics, optics-classic, dbscan, none)", v);
            }
            c->cal.filter = v;
            ++i;
        } else if (strcmp(a, "--eps") == 0) {
            if (parse_double(v, &c->cal.eps) != 0 || !(c->cal.eps > 0.0)) {
                return usage_error("--eps needs a positive number, got \"%s\"", v);
            }
            ++i;
        } else if (strcmp(a, "--min-pts") == 0) {
            size_t n;
            if (parse_size(v, strlen(v), &n) != 0 || n < 1u || n > 100000u) {
                return usage_error("--min-pts needs a positive integer, got \"%s\"", v);
            }
            c->cal.min_pts = (long)n;
            ++i;
        } else if (strcmp(a, "--declination") == 0) {
            if (parse_double(v, &c->declination) != 0 || fabs(c->declination) > 180.0) {
                return usage_error("--declination needs degrees in [-180, 180], got \"%s\"", v);
            }
            ++i;
        } else if (strcmp(a, "--plane") == 0) {
            c->plane_name = v;
            ++i;
        } else if (strcmp(a, "--headings") == 0) {
            c->headings_path = v;
            ++i;
        } else if (a[0] == '-' && a[1] != '\0') {
            return usage_error("unknown option %s", a);
        } else if (c->path != NULL) {
            return usage_error("more than one dump given (%s)", a);
        } else {
            c->path = a;
        }
    }
    if (c->path == NULL) {
        return usage_error("%s", "no dump file given");
    }
    if (strcmp(c->cal.filter, "none") == 0 && (isfinite(c->cal.eps) || c->cal.min_pts > 0)) {
        return usage_error("%s", "--eps/--min-pts make no sense with --filter none");
    }
    if (magcal_replay_csv_plane(c->plane_name, &c->cal.plane) != MAGCAL_OK) {
        return usage_error("--plane must be XY, XZ or YZ (or YX, ZX, ZY), got \"%s\"", c->plane_name);
    }
    return -1; /* continue */
}

/* Parse "A:B", "A:", ":B" against n rows. 0 ok, -1 bad. */
static int parse_range(const char *s, size_t n, size_t *a, size_t *b, char *msg, size_t msg_len)
{
    const char *colon = strchr(s, ':');
    if (colon == NULL) {
        (void)snprintf(msg, msg_len, "--cal-range must be A:B, got \"%s\"", s);
        return -1;
    }
    *a = 0u;
    *b = n;
    if ((colon > s && parse_size(s, (size_t)(colon - s), a) != 0) ||
        (colon[1] != '\0' && parse_size(colon + 1, strlen(colon + 1), b) != 0)) {
        (void)snprintf(msg, msg_len, "--cal-range must be A:B with row numbers, got \"%s\"", s);
        return -1;
    }
    if (*a >= *b || *b > n) {
        (void)snprintf(msg, msg_len, "--cal-range %s is empty or beyond the dump's %lu rows", s,
                       (unsigned long)n);
        return -1;
    }
    return 0;
}

int main(int argc, char **argv)
{
    cli_t c;
    magcal_replay_csv_t d;
    replay_report_t r;
    replay_result_t res;
    char err[MAGCAL_REPLAY_CSV_ERR_LEN];
    uint32_t required;
    int rc;
    size_t i, n;
    magcal_vec3_t *fed = NULL;
    double *raw_rad = NULL, *cor_rad = NULL, *err_deg = NULL, *hdg = NULL, *raw_hdg = NULL;
    unsigned char *flag = NULL, *use = NULL, *fedmask = NULL;
    const double *ref;
    static const double k_nan = NAN;

    rc = parse_args(argc, argv, &c);
    if (rc >= 0) {
        return rc;
    }
    memset(&d, 0, sizeof d);
    memset(&r, 0, sizeof r);
    memset(&res, 0, sizeof res);
    required = MAGCAL_REPLAY_COL_BIT(MAGCAL_REPLAY_COL_MX + c.cal.plane.src[0]) |
               MAGCAL_REPLAY_COL_BIT(MAGCAL_REPLAY_COL_MX + c.cal.plane.src[1]);
    if (magcal_replay_csv_read(c.path, required, &d, err, sizeof err) != MAGCAL_OK) {
        fprintf(stderr, "magcal-replay: %s\n", err);
        return REPLAY_EXIT_INPUT;
    }
    n = d.n_rows;
    r.file = c.path;
    r.filter = c.cal.filter;
    r.plane = c.plane_name;
    r.declination_deg = c.declination;
    r.eps = c.cal.eps;
    r.min_pts = c.cal.min_pts;
    r.n_rows = n;
    r.cal_first = 0u;
    r.cal_end = n;
    if (c.range != NULL && parse_range(c.range, n, &r.cal_first, &r.cal_end, err, sizeof err) != 0) {
        fprintf(stderr, "magcal-replay: %s\n", err);
        magcal_replay_csv_free(&d);
        return REPLAY_EXIT_INPUT;
    }
    r.n_cal = r.cal_end - r.cal_first;

    /* Decimation: the calibrator holds at most `capacity` samples; feed every k-th row. */
    r.capacity = replay_capacity();
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
    flag = (unsigned char *)calloc(n, 1u);
    use = (unsigned char *)calloc(n, 1u);
    fedmask = (unsigned char *)calloc(n, 1u);
    res.flags = (unsigned char *)calloc(r.n_fed, 1u);
    if (!fed || !raw_rad || !cor_rad || !err_deg || !hdg || !raw_hdg || !flag || !use || !fedmask || !res.flags) {
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

    /* Calibrate: replay port serves the (decimated) calibration rows; the calibrator polls. */
    rc = replay_calibrate(&c.cal, &d, r.cal_first, r.n_fed, r.decimation, &r, &res);
    if (rc != REPLAY_EXIT_OK && rc != REPLAY_EXIT_CAL_FAILED) {
        goto done;
    }

    /* Per-row headings and flags. */
    ref = d.col[MAGCAL_REPLAY_COL_HEADING_REF];
    for (i = 0u; i < n; ++i) {
        magcal_vec2_t raw = {fed[i].x, fed[i].y};
        raw_rad[i] = sqrt((double)raw.x * raw.x + (double)raw.y * raw.y);
        raw_hdg[i] = (raw_rad[i] > 0.0)
                         ? wrap360(atan2(-(double)raw.x, (double)raw.y) * k_deg_per_rad + c.declination)
                         : NAN;
        hdg[i] = NAN;
        err_deg[i] = NAN;
        cor_rad[i] = NAN;
        if (rc == REPLAY_EXIT_OK) {
            magcal_vec2_t h;
            float mag_deg = 0.0f, true_deg = 0.0f;
            if (magcal_correct_apply(&res.cal, raw, &h) == MAGCAL_OK) {
                cor_rad[i] = sqrt((double)h.x * h.x + (double)h.y * h.y);
            }
            if (magcal_heading_compute(&res.cal, raw, (float)c.declination, &mag_deg, &true_deg) ==
                MAGCAL_OK) {
                hdg[i] = true_deg;
            }
            if (i >= r.cal_first && i < r.cal_end && (i - r.cal_first) % r.decimation == 0u) {
                size_t k = (i - r.cal_first) / r.decimation;
                flag[i] = res.flags[k];
                use[i] = (unsigned char)!res.flags[k];
            } else {
                flag[i] = (unsigned char)replay_classify(&res, raw);
            }
            if (ref != NULL && isfinite(ref[i]) && isfinite(hdg[i])) {
                err_deg[i] = wrap180(hdg[i] - ref[i]);
            }
        }
    }
    if (rc == REPLAY_EXIT_OK) {
        /* raw spread over the samples used (same set as the corrected one), and over every
         * fed calibration sample (outliers included) */
        r.spread_raw = spread(raw_rad, use, n);
        for (i = r.cal_first; i < r.cal_end; i += r.decimation) {
            fedmask[i] = 1u;
        }
        r.spread_raw_all = spread(raw_rad, fedmask, n);
        r.spread_corrected = spread(cor_rad, use, n);
        heading_metrics(&r, ref != NULL ? ref : &k_nan, err_deg, flag, ref != NULL ? n : 0u);
    }
    /* truth flags of the dump (glitch on recorded dumps, outlier on synthetic ones) */
    {
        const double *truth = d.col[MAGCAL_REPLAY_COL_GLITCH];
        r.truth_column = "glitch";
        if (truth == NULL) {
            truth = d.col[MAGCAL_REPLAY_COL_OUTLIER];
            r.truth_column = "outlier";
        }
        if (truth == NULL || rc != REPLAY_EXIT_OK) {
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
        FILE *f = fopen(c.headings_path, "w");
        int bad = (f == NULL);
        if (f != NULL) {
            fprintf(f, "index,raw_heading_deg,heading_deg,outlier%s\n",
                    ref != NULL ? ",heading_ref_deg,error_deg" : "");
            for (i = 0u; i < n; ++i) {
                fprintf(f, "%lu,%.4f,%.4f,%d", (unsigned long)i, raw_hdg[i], hdg[i], flag[i]);
                if (ref != NULL) {
                    fprintf(f, ",%.4f,%.4f", ref[i], err_deg[i]);
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
    free(flag);
    free(use);
    free(fedmask);
    free(res.flags);
    magcal_replay_csv_free(&d);
    return rc;
}
