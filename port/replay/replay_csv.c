/* Host-only CSV dump reader (see replay_csv.h). Every byte access is bounded by the buffer
 * length; every limit is checked before it can overflow. */
#include "replay_csv.h"

#include <errno.h>
#include <float.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const char *const k_col_names[MAGCAL_REPLAY_COL_COUNT] = {
    "t", "mx", "my", "mz", "ax", "ay", "az", "heading_ref_deg", "cog_deg", "speed_mps", "glitch",
    "outlier", "roll_deg", "pitch_deg", "yaw_deg", "lat_deg", "lon_deg", "height_km",
    "decimal_year", "dop", "gx", "gy", "gz"};

const char *magcal_replay_csv_col_name(magcal_replay_col_t c)
{
    if ((int)c < 0 || c >= MAGCAL_REPLAY_COL_COUNT) {
        return "?";
    }
    return k_col_names[c];
}

/* ------------------------------------------------------------------ messages */

typedef struct {
    const char *name;
    char *err;
    size_t err_len;
    char sep; /* field separator of the file: ',' (default), ';' or '\t' (from the header) */
} ctx_t;

static void set_err(const ctx_t *cx, size_t line, size_t col, const char *fmt, ...)
{
    char msg[MAGCAL_REPLAY_CSV_ERR_LEN];
    va_list ap;
    if (cx->err == NULL || cx->err_len == 0u) {
        return;
    }
    va_start(ap, fmt);
    (void)vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    if (line == 0u) {
        (void)snprintf(cx->err, cx->err_len, "%s: %s", cx->name, msg);
    } else if (col == 0u) {
        (void)snprintf(cx->err, cx->err_len, "%s:%lu: %s", cx->name, (unsigned long)line, msg);
    } else {
        (void)snprintf(cx->err, cx->err_len, "%s:%lu:%lu: %s", cx->name, (unsigned long)line,
                       (unsigned long)col, msg);
    }
}

/* Printable, bounded rendering of a cell for messages (non-printables as \xNN). */
static void quote_cell(const char *s, size_t n, char *out, size_t out_len)
{
    static const size_t k_show = 40u;
    size_t i, o = 0u;
    for (i = 0u; i < n && i < k_show && o + 5u < out_len; ++i) {
        unsigned char ch = (unsigned char)s[i];
        if (ch >= 0x20u && ch < 0x7fu && ch != '"' && ch != '\\') {
            out[o++] = (char)ch;
        } else {
            (void)snprintf(out + o, out_len - o, "\\x%02X", (unsigned)ch);
            o += 4u;
        }
    }
    if (i < n && o + 4u < out_len) {
        out[o++] = '.';
        out[o++] = '.';
        out[o++] = '.';
    }
    out[o] = '\0';
}

/* ------------------------------------------------------------------ cells */

static int is_blank(char c) { return c == ' ' || c == '\t'; }

static int lower(int c) { return (c >= 'A' && c <= 'Z') ? c - 'A' + 'a' : c; }

/* Trim blanks, then one pair of surrounding double quotes (and blanks inside them). */
static void trim(const char **s, size_t *n)
{
    const char *p = *s;
    size_t len = *n;
    while (len > 0u && is_blank(p[0])) {
        ++p;
        --len;
    }
    while (len > 0u && is_blank(p[len - 1u])) {
        --len;
    }
    if (len >= 2u && p[0] == '"' && p[len - 1u] == '"') {
        ++p;
        len -= 2u;
        while (len > 0u && is_blank(p[0])) {
            ++p;
            --len;
        }
        while (len > 0u && is_blank(p[len - 1u])) {
            --len;
        }
    }
    *s = p;
    *n = len;
}

static int eq_nocase(const char *s, size_t n, const char *lit)
{
    size_t i;
    for (i = 0u; i < n; ++i) {
        if (lit[i] == '\0' || lower((unsigned char)s[i]) != lit[i]) {
            return 0;
        }
    }
    return lit[n] == '\0';
}

/* Strict decimal syntax: [+-] digits [. digits] [(e|E) [+-] digits], at least one mantissa digit. */
static int is_decimal(const char *s, size_t n)
{
    size_t i = 0u, digits = 0u;
    if (i < n && (s[i] == '+' || s[i] == '-')) {
        ++i;
    }
    while (i < n && s[i] >= '0' && s[i] <= '9') {
        ++i;
        ++digits;
    }
    if (i < n && s[i] == '.') {
        ++i;
        while (i < n && s[i] >= '0' && s[i] <= '9') {
            ++i;
            ++digits;
        }
    }
    if (digits == 0u) {
        return 0;
    }
    if (i < n && (s[i] == 'e' || s[i] == 'E')) {
        size_t ed = 0u;
        ++i;
        if (i < n && (s[i] == '+' || s[i] == '-')) {
            ++i;
        }
        while (i < n && s[i] >= '0' && s[i] <= '9') {
            ++i;
            ++ed;
        }
        if (ed == 0u) {
            return 0;
        }
    }
    return i == n;
}

/* 0 ok (value in *v, NaN for missing), 1 missing-but-required, 2 not a number, 3 too long,
 * 4 out of range. */
static int parse_cell(const char *s, size_t n, int required, double *v)
{
    char buf[MAGCAL_REPLAY_CSV_MAX_NUMBER_LEN + 1u];
    char *end = NULL;
    double x;
    if (n == 0u || eq_nocase(s, n, "nan")) {
        *v = NAN;
        return required ? 1 : 0;
    }
    if (!is_decimal(s, n)) {
        return 2;
    }
    if (n > MAGCAL_REPLAY_CSV_MAX_NUMBER_LEN) {
        return 3;
    }
    memcpy(buf, s, n);
    buf[n] = '\0';
    errno = 0;
    x = strtod(buf, &end);
    if (end != buf + n) {
        return 2;
    }
    /* beyond FLT_MAX the conversion to the library's float32 would be undefined (C99 6.3.1.5) */
    if (!isfinite(x) || (errno == ERANGE && fabs(x) > 1.0) || fabs(x) > (double)FLT_MAX) {
        return 4;
    }
    *v = x;
    return 0;
}

/* ------------------------------------------------------------------ parser */

void magcal_replay_csv_free(magcal_replay_csv_t *d)
{
    size_t c;
    if (d == NULL) {
        return;
    }
    for (c = 0u; c < (size_t)MAGCAL_REPLAY_COL_COUNT; ++c) {
        free(d->col[c]);
        d->col[c] = NULL;
    }
    free(d->line);
    d->line = NULL;
    d->n_rows = 0u;
}

/* Grow every present column and the line array to hold `want` rows. 0 ok, -1 out of memory. */
static int grow(magcal_replay_csv_t *d, size_t *cap, size_t want)
{
    size_t c, ncap;
    if (want <= *cap) {
        return 0;
    }
    ncap = (*cap == 0u) ? 1024u : *cap * 2u;
    if (ncap > MAGCAL_REPLAY_CSV_MAX_ROWS) {
        ncap = MAGCAL_REPLAY_CSV_MAX_ROWS;
    }
    for (c = 0u; c < (size_t)MAGCAL_REPLAY_COL_COUNT; ++c) {
        if (d->col[c] != NULL) {
            double *p = (double *)realloc(d->col[c], ncap * sizeof(double));
            if (p == NULL) {
                return -1;
            }
            d->col[c] = p;
        }
    }
    {
        size_t *p = (size_t *)realloc(d->line, ncap * sizeof(size_t));
        if (p == NULL) {
            return -1;
        }
        d->line = p;
    }
    *cap = ncap;
    return 0;
}

/* Column map of the header: recognised id per field, or -1. */
typedef struct {
    size_t n_fields;
    signed char *id; /* n_fields entries */
} header_t;

/* ------------------------------------------------------------------ header help */

/* Likely meanings of common header spellings (the name reduced by norm_name()), so a message can
 * say "mag_x -> mx". Only suggested, never applied: nothing is guessed. */
typedef struct {
    const char *alias;
    int col;
} alias_t;

static const alias_t k_aliases[] = {
    {"time", MAGCAL_REPLAY_COL_T}, {"timestamp", MAGCAL_REPLAY_COL_T}, {"ts", MAGCAL_REPLAY_COL_T},
    {"sec", MAGCAL_REPLAY_COL_T}, {"seconds", MAGCAL_REPLAY_COL_T},
    {"mx", MAGCAL_REPLAY_COL_MX}, {"magx", MAGCAL_REPLAY_COL_MX}, {"x", MAGCAL_REPLAY_COL_MX},
    {"bx", MAGCAL_REPLAY_COL_MX}, {"hx", MAGCAL_REPLAY_COL_MX}, {"magnetometerx", MAGCAL_REPLAY_COL_MX},
    {"magneticx", MAGCAL_REPLAY_COL_MX}, {"compassx", MAGCAL_REPLAY_COL_MX}, {"xmag", MAGCAL_REPLAY_COL_MX},
    {"my", MAGCAL_REPLAY_COL_MY}, {"magy", MAGCAL_REPLAY_COL_MY}, {"y", MAGCAL_REPLAY_COL_MY},
    {"by", MAGCAL_REPLAY_COL_MY}, {"hy", MAGCAL_REPLAY_COL_MY}, {"magnetometery", MAGCAL_REPLAY_COL_MY},
    {"magneticy", MAGCAL_REPLAY_COL_MY}, {"compassy", MAGCAL_REPLAY_COL_MY}, {"ymag", MAGCAL_REPLAY_COL_MY},
    {"mz", MAGCAL_REPLAY_COL_MZ}, {"magz", MAGCAL_REPLAY_COL_MZ}, {"z", MAGCAL_REPLAY_COL_MZ},
    {"bz", MAGCAL_REPLAY_COL_MZ}, {"hz", MAGCAL_REPLAY_COL_MZ}, {"magnetometerz", MAGCAL_REPLAY_COL_MZ},
    {"magneticz", MAGCAL_REPLAY_COL_MZ}, {"compassz", MAGCAL_REPLAY_COL_MZ}, {"zmag", MAGCAL_REPLAY_COL_MZ},
    {"ax", MAGCAL_REPLAY_COL_AX}, {"accx", MAGCAL_REPLAY_COL_AX}, {"accelx", MAGCAL_REPLAY_COL_AX},
    {"accelerometerx", MAGCAL_REPLAY_COL_AX}, {"xacc", MAGCAL_REPLAY_COL_AX},
    {"ay", MAGCAL_REPLAY_COL_AY}, {"accy", MAGCAL_REPLAY_COL_AY}, {"accely", MAGCAL_REPLAY_COL_AY},
    {"accelerometery", MAGCAL_REPLAY_COL_AY}, {"yacc", MAGCAL_REPLAY_COL_AY},
    {"az", MAGCAL_REPLAY_COL_AZ}, {"accz", MAGCAL_REPLAY_COL_AZ}, {"accelz", MAGCAL_REPLAY_COL_AZ},
    {"accelerometerz", MAGCAL_REPLAY_COL_AZ}, {"zacc", MAGCAL_REPLAY_COL_AZ},
    {"heading", MAGCAL_REPLAY_COL_HEADING_REF}, {"headingref", MAGCAL_REPLAY_COL_HEADING_REF},
    {"refheading", MAGCAL_REPLAY_COL_HEADING_REF}, {"hdg", MAGCAL_REPLAY_COL_HEADING_REF},
    {"headingtrue", MAGCAL_REPLAY_COL_HEADING_REF}, {"trueheading", MAGCAL_REPLAY_COL_HEADING_REF},
    {"reference", MAGCAL_REPLAY_COL_HEADING_REF}, {"ref", MAGCAL_REPLAY_COL_HEADING_REF},
    {"cog", MAGCAL_REPLAY_COL_COG}, {"course", MAGCAL_REPLAY_COL_COG},
    {"speed", MAGCAL_REPLAY_COL_SPEED}, {"groundspeed", MAGCAL_REPLAY_COL_SPEED},
    {"roll", MAGCAL_REPLAY_COL_ROLL}, {"pitch", MAGCAL_REPLAY_COL_PITCH}, {"yaw", MAGCAL_REPLAY_COL_YAW},
    {"lat", MAGCAL_REPLAY_COL_LAT}, {"latitude", MAGCAL_REPLAY_COL_LAT},
    {"lon", MAGCAL_REPLAY_COL_LON}, {"lng", MAGCAL_REPLAY_COL_LON}, {"longitude", MAGCAL_REPLAY_COL_LON},
    {"height", MAGCAL_REPLAY_COL_HEIGHT}, {"alt", MAGCAL_REPLAY_COL_HEIGHT},
    {"altitude", MAGCAL_REPLAY_COL_HEIGHT}, {"year", MAGCAL_REPLAY_COL_YEAR},
    {"decimalyear", MAGCAL_REPLAY_COL_YEAR}, {"hdop", MAGCAL_REPLAY_COL_DOP},
    {"pdop", MAGCAL_REPLAY_COL_DOP},
    {"gx", MAGCAL_REPLAY_COL_GX}, {"gyrox", MAGCAL_REPLAY_COL_GX}, {"gyrx", MAGCAL_REPLAY_COL_GX},
    {"gyroscopex", MAGCAL_REPLAY_COL_GX},
    {"gy", MAGCAL_REPLAY_COL_GY}, {"gyroy", MAGCAL_REPLAY_COL_GY}, {"gyry", MAGCAL_REPLAY_COL_GY},
    {"gyroscopey", MAGCAL_REPLAY_COL_GY},
    {"gz", MAGCAL_REPLAY_COL_GZ}, {"gyroz", MAGCAL_REPLAY_COL_GZ}, {"gyrz", MAGCAL_REPLAY_COL_GZ},
    {"gyroscopez", MAGCAL_REPLAY_COL_GZ}};

/* Unit words dropped from a header name ("mx (uT)", "mag_x_ut", "heading_deg"). */
static const char *const k_units[] = {"ut", "nt", "gauss", "mgauss", "g", "mg", "lsb", "counts",
                                      "mps2", "ms2", "deg", "degrees", "rad", "s", "ms", "m", "km"};

static int is_alnum(char c)
{
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9');
}

/* Reduce a header name to its lower-case alphanumeric tokens joined, without a trailing unit
 * word or a bracketed part: "Mag_X (uT)" -> "magx", "heading_deg" -> "heading". The dropped unit
 * (first one found) goes to unit (lower case, "" when none). 0 when nothing is left. */
static size_t norm_name(const char *s, size_t n, char *out, size_t out_len, char *unit, size_t unit_len)
{
    char tok[8][24];
    size_t nt = 0u, i = 0u, o = 0u, k;
    unit[0] = '\0';
    while (i < n && nt < 8u) {
        size_t t = 0u;
        int bracket = 0;
        while (i < n && !is_alnum(s[i])) {
            bracket |= (s[i] == '(' || s[i] == '[' || s[i] == '{');
            ++i;
        }
        while (i < n && is_alnum(s[i])) {
            if (t + 1u < sizeof tok[0]) {
                tok[nt][t++] = (char)lower((unsigned char)s[i]);
            }
            ++i;
        }
        tok[nt][t] = '\0';
        if (t == 0u) {
            break;
        }
        if (bracket) { /* "(uT)": a unit, or a remark; not part of the name */
            if (unit[0] == '\0') {
                (void)snprintf(unit, unit_len, "%s", tok[nt]);
            }
            while (i < n && s[i] != ')' && s[i] != ']' && s[i] != '}') {
                ++i;
            }
            continue;
        }
        ++nt;
    }
    if (nt > 1u) { /* a trailing unit word: "mag_x_ut", "heading_deg" */
        for (k = 0u; k < sizeof k_units / sizeof k_units[0]; ++k) {
            if (strcmp(tok[nt - 1u], k_units[k]) == 0) {
                if (unit[0] == '\0') {
                    (void)snprintf(unit, unit_len, "%s", tok[nt - 1u]);
                }
                --nt;
                break;
            }
        }
    }
    for (k = 0u; k < nt; ++k) {
        size_t t = strlen(tok[k]);
        if (o + t + 1u > out_len) {
            break;
        }
        memcpy(out + o, tok[k], t);
        o += t;
    }
    out[o] = '\0';
    return o;
}

/* Recognised column a header name probably means (-1: no idea). */
static int suggest_col(const char *s, size_t n, char *unit, size_t unit_len)
{
    char key[64];
    size_t k;
    if (norm_name(s, n, key, sizeof key, unit, unit_len) == 0u) {
        return -1;
    }
    for (k = 0u; k < (size_t)MAGCAL_REPLAY_COL_COUNT; ++k) { /* "roll_deg" -> "rolldeg" */
        char canon[64], u2[16];
        (void)norm_name(k_col_names[k], strlen(k_col_names[k]), canon, sizeof canon, u2, sizeof u2);
        if (strcmp(canon, key) == 0) {
            return (int)k;
        }
    }
    for (k = 0u; k < sizeof k_aliases / sizeof k_aliases[0]; ++k) {
        if (strcmp(k_aliases[k].alias, key) == 0) {
            return k_aliases[k].col;
        }
    }
    return -1;
}

/* Append printf text to out[len] (bounded; the end is cut, never overrun). */
static void append(char *out, size_t len, const char *fmt, ...)
{
    size_t used = strlen(out);
    va_list ap;
    if (used + 1u >= len) {
        return;
    }
    va_start(ap, fmt);
    (void)vsnprintf(out + used, len - used, fmt, ap);
    va_end(ap);
}

/* What the header holds, for messages: the names found (quoted), the suggested renames of the
 * unrecognised ones, and the accepted names. `unknown_only`: list only the unrecognised names
 * (the note of a successful read). Returns the number of unrecognised fields. */
static size_t describe_header(const char *p, size_t n, char sep, const header_t *h, const int *seen,
                              int unknown_only, char *out, size_t len)
{
    size_t i, f = 0u, start = 0u, n_unknown = 0u, n_sugg = 0u, n_listed = 0u;
    char sugg[MAGCAL_REPLAY_CSV_NOTE_LEN];
    char shown[80], unit[16];
    out[0] = '\0';
    sugg[0] = '\0';
    if (!unknown_only) {
        append(out, len, "found:");
    }
    for (i = 0u; i <= n && f < h->n_fields; ++i) {
        if (i == n || p[i] == sep) {
            const char *s = p + start;
            size_t l = i - start;
            trim(&s, &l);
            quote_cell(s, l, shown, sizeof shown);
            if (h->id[f] < 0) {
                int c = suggest_col(s, l, unit, sizeof unit);
                append(out, len, "%s\"%s\"", n_listed ? ", " : " ", shown);
                ++n_listed;
                ++n_unknown;
                if (c >= 0 && seen[c] == 0) {
                    append(sugg, sizeof sugg, "%s\"%s\" -> %s%s%s%s", n_sugg ? ", " : "", shown,
                           k_col_names[c], unit[0] ? " (unit " : "", unit, unit[0] ? ")" : "");
                    ++n_sugg;
                }
            } else if (!unknown_only) {
                append(out, len, "%s%s", n_listed ? ", " : " ", k_col_names[h->id[f]]);
                ++n_listed;
            }
            ++f;
            start = i + 1u;
        }
    }
    if (n_sugg > 0u) {
        append(out, len, "; did you mean %s? (rename the header; units are not read from it)", sugg);
    }
    if (!unknown_only || n_unknown > 0u) {
        append(out, len, "; accepted names:");
        for (i = 0u; i < (size_t)MAGCAL_REPLAY_COL_COUNT; ++i) {
            append(out, len, "%s %s", i ? "," : "", k_col_names[i]);
        }
    }
    return n_unknown;
}

static magcal_status_t parse_header(const ctx_t *cx, const char *p, size_t n, size_t line_no,
                                    uint32_t required, header_t *h, magcal_replay_csv_t *d)
{
    size_t nf = 1u, i, f = 0u, start = 0u;
    int seen[MAGCAL_REPLAY_COL_COUNT];
    for (i = 0u; i < n; ++i) {
        nf += (p[i] == cx->sep) ? 1u : 0u;
    }
    if (nf > MAGCAL_REPLAY_CSV_MAX_FIELDS) {
        set_err(cx, line_no, 0u, "header has %lu fields, more than the limit %u",
                (unsigned long)nf, MAGCAL_REPLAY_CSV_MAX_FIELDS);
        return MAGCAL_ERR_BUFFER_FULL;
    }
    h->id = (signed char *)malloc(nf);
    if (h->id == NULL) {
        set_err(cx, 0u, 0u, "out of memory");
        return MAGCAL_ERR_BUFFER_FULL;
    }
    h->n_fields = nf;
    memset(seen, 0, sizeof seen);
    for (i = 0u; i <= n; ++i) {
        if (i == n || p[i] == cx->sep) {
            const char *s = p + start;
            size_t len = i - start;
            int c, id = -1;
            trim(&s, &len);
            for (c = 0; c < (int)MAGCAL_REPLAY_COL_COUNT; ++c) {
                if (eq_nocase(s, len, k_col_names[c])) {
                    id = c;
                }
            }
            if (id >= 0) {
                if (seen[id] != 0) {
                    set_err(cx, line_no, f + 1u, "duplicate column \"%s\" (first at field %d)",
                            k_col_names[id], seen[id]);
                    return MAGCAL_ERR_ARG;
                }
                seen[id] = (int)(f + 1u);
            }
            h->id[f++] = (signed char)id;
            start = i + 1u;
        }
    }
    for (i = 0u; i < (size_t)MAGCAL_REPLAY_COL_COUNT; ++i) {
        if ((required & MAGCAL_REPLAY_COL_BIT(i)) != 0u && seen[i] == 0) {
            char what[MAGCAL_REPLAY_CSV_NOTE_LEN];
            (void)describe_header(p, n, cx->sep, h, seen, 0, what, sizeof what);
            set_err(cx, line_no, 0u, "missing required column \"%s\" in the header (%s; %s)%s",
                    k_col_names[i],
                    cx->sep == ';' ? "read as ';'-separated" : cx->sep == '\t' ? "read as tab-separated"
                                                                                : "read as comma-separated",
                    what,
                    (nf == 1u && memchr(p, ' ', n) != NULL)
                        ? "; the header is one field: space-separated? (fields are separated by ',', ';' or tab)"
                        : "");
            return MAGCAL_ERR_ARG;
        }
    }
    /* d->note: the columns that are not read, with suggestions ("" when none; the caller warns) */
    (void)describe_header(p, n, cx->sep, h, seen, 1, d->note, sizeof d->note);
    for (i = 0u; i < (size_t)MAGCAL_REPLAY_COL_COUNT; ++i) {
        if (seen[i] != 0) {
            d->col[i] = (double *)malloc(sizeof(double)); /* grown per row; non-NULL = present */
            if (d->col[i] == NULL) {
                set_err(cx, 0u, 0u, "out of memory");
                return MAGCAL_ERR_BUFFER_FULL;
            }
        }
    }
    return MAGCAL_OK;
}

static magcal_status_t parse_row(const ctx_t *cx, const char *p, size_t n, size_t line_no,
                                 uint32_t required, const header_t *h, magcal_replay_csv_t *d,
                                 size_t row)
{
    size_t nf = 1u, i, f = 0u, start = 0u;
    for (i = 0u; i < n; ++i) {
        nf += (p[i] == cx->sep) ? 1u : 0u;
    }
    if (nf != h->n_fields) {
        set_err(cx, line_no, (nf < h->n_fields ? nf : h->n_fields) + 1u,
                "row has %lu fields but the header has %lu%s", (unsigned long)nf,
                (unsigned long)h->n_fields, nf < h->n_fields ? " (truncated line?)" : "");
        return MAGCAL_ERR_ARG;
    }
    for (i = 0u; i <= n; ++i) {
        if (i == n || p[i] == cx->sep) {
            int id = h->id[f];
            if (id >= 0) {
                const char *s = p + start;
                size_t len = i - start;
                double v = NAN;
                int req = (required & MAGCAL_REPLAY_COL_BIT(id)) != 0u;
                int rc;
                char shown[200];
                trim(&s, &len);
                rc = parse_cell(s, len, req, &v);
                quote_cell(s, len, shown, sizeof shown);
                switch (rc) {
                case 0:
                    break;
                case 1:
                    set_err(cx, line_no, f + 1u, "column \"%s\" is required, got %s",
                            k_col_names[id], len == 0u ? "an empty cell" : "\"nan\"");
                    return MAGCAL_ERR_ARG;
                case 3:
                    set_err(cx, line_no, f + 1u, "number longer than %u characters in column \"%s\"",
                            MAGCAL_REPLAY_CSV_MAX_NUMBER_LEN, k_col_names[id]);
                    return MAGCAL_ERR_ARG;
                case 4:
                    set_err(cx, line_no, f + 1u, "number out of range, got \"%s\" (column %s)",
                            shown, k_col_names[id]);
                    return MAGCAL_ERR_ARG;
                default:
                    set_err(cx, line_no, f + 1u, "expected a number, got \"%s\" (column %s)",
                            shown, k_col_names[id]);
                    return MAGCAL_ERR_ARG;
                }
                d->col[id][row] = v;
            }
            ++f;
            start = i + 1u;
        }
    }
    d->line[row] = line_no;
    return MAGCAL_OK;
}

magcal_status_t magcal_replay_csv_parse(const char *text, size_t len, const char *name,
                                        uint32_t required, magcal_replay_csv_t *out, char *err,
                                        size_t err_len)
{
    ctx_t cx;
    magcal_replay_csv_t d;
    header_t h;
    size_t pos = 0u, line_no = 0u, cap = 0u;
    int have_header = 0;
    magcal_status_t st = MAGCAL_OK;

    cx.name = (name != NULL) ? name : "<input>";
    cx.err = err;
    cx.err_len = err_len;
    cx.sep = ',';
    if (err != NULL && err_len > 0u) {
        err[0] = '\0';
    }
    if (out == NULL || (text == NULL && len > 0u)) {
        set_err(&cx, 0u, 0u, "internal error: NULL argument");
        return MAGCAL_ERR_NULL;
    }
    memset(out, 0, sizeof *out);
    memset(&d, 0, sizeof d);
    h.n_fields = 0u;
    h.id = NULL;
    if (len > MAGCAL_REPLAY_CSV_MAX_BYTES) {
        set_err(&cx, 0u, 0u, "file larger than %u bytes", MAGCAL_REPLAY_CSV_MAX_BYTES);
        return MAGCAL_ERR_BUFFER_FULL;
    }
    if (len >= 3u && (unsigned char)text[0] == 0xEFu && (unsigned char)text[1] == 0xBBu &&
        (unsigned char)text[2] == 0xBFu) {
        pos = 3u;
    }
    while (pos < len && st == MAGCAL_OK) {
        const char *p = text + pos;
        const char *nl = (const char *)memchr(p, '\n', len - pos);
        size_t n = (nl != NULL) ? (size_t)(nl - p) : len - pos;
        size_t k = 0u;
        pos += n + ((nl != NULL) ? 1u : 0u);
        ++line_no;
        if (n > 0u && p[n - 1u] == '\r') {
            --n;
        }
        if (memchr(p, '\0', n) != NULL) {
            set_err(&cx, line_no, 0u, "NUL byte in the line (binary file?)");
            st = MAGCAL_ERR_ARG;
            break;
        }
        while (k < n && (is_blank(p[k]) || p[k] == '\r')) {
            ++k;
        }
        if (k == n || p[k] == '#') {
            continue; /* blank or comment */
        }
        if (!have_header) {
            /* separator: ',' unless the header has none and is ';'- or tab-separated */
            if (memchr(p, ',', n) == NULL && memchr(p, ';', n) != NULL) {
                cx.sep = ';';
            } else if (memchr(p, ',', n) == NULL && memchr(p, '\t', n) != NULL) {
                cx.sep = '\t';
            }
            d.sep = cx.sep;
            st = parse_header(&cx, p, n, line_no, required, &h, &d);
            have_header = 1;
            continue;
        }
        if (d.n_rows >= MAGCAL_REPLAY_CSV_MAX_ROWS) {
            set_err(&cx, line_no, 0u, "more than %u data rows", MAGCAL_REPLAY_CSV_MAX_ROWS);
            st = MAGCAL_ERR_BUFFER_FULL;
            break;
        }
        if (grow(&d, &cap, d.n_rows + 1u) != 0) {
            set_err(&cx, line_no, 0u, "out of memory");
            st = MAGCAL_ERR_BUFFER_FULL;
            break;
        }
        st = parse_row(&cx, p, n, line_no, required, &h, &d, d.n_rows);
        if (st == MAGCAL_OK) {
            d.n_rows++;
        }
    }
    free(h.id);
    if (st == MAGCAL_OK && !have_header) {
        set_err(&cx, 0u, 0u, "no header row (empty file, or only comments)");
        st = MAGCAL_ERR_NO_DATA;
    } else if (st == MAGCAL_OK && d.n_rows == 0u) {
        set_err(&cx, 0u, 0u, "no data rows after the header");
        st = MAGCAL_ERR_NO_DATA;
    }
    if (st != MAGCAL_OK) {
        magcal_replay_csv_free(&d);
        return st;
    }
    *out = d;
    return MAGCAL_OK;
}

magcal_status_t magcal_replay_csv_read(const char *path, uint32_t required,
                                       magcal_replay_csv_t *out, char *err, size_t err_len)
{
    ctx_t cx;
    FILE *f;
    char *buf = NULL;
    size_t len = 0u, cap = 0u;
    magcal_status_t st;
    int is_stdin;

    cx.name = (path != NULL) ? path : "<null>";
    cx.err = err;
    cx.err_len = err_len;
    cx.sep = ',';
    if (path == NULL || out == NULL) {
        set_err(&cx, 0u, 0u, "internal error: NULL argument");
        return MAGCAL_ERR_NULL;
    }
    is_stdin = strcmp(path, "-") == 0;
    if (is_stdin) {
        cx.name = "<stdin>";
        f = stdin;
    } else {
        errno = 0;
        f = fopen(path, "rb");
        if (f == NULL) {
            set_err(&cx, 0u, 0u, "cannot open: %s", errno != 0 ? strerror(errno) : "unknown error");
            return MAGCAL_ERR_PORT;
        }
    }
    for (;;) {
        size_t got;
        if (len == cap) {
            size_t ncap = (cap == 0u) ? 65536u : cap * 2u;
            char *nb;
            if (cap >= (size_t)MAGCAL_REPLAY_CSV_MAX_BYTES + 1u) {
                break; /* already over the limit; parse reports it */
            }
            if (ncap > (size_t)MAGCAL_REPLAY_CSV_MAX_BYTES + 1u) {
                ncap = (size_t)MAGCAL_REPLAY_CSV_MAX_BYTES + 1u;
            }
            nb = (char *)realloc(buf, ncap);
            if (nb == NULL) {
                free(buf);
                if (!is_stdin) {
                    (void)fclose(f);
                }
                set_err(&cx, 0u, 0u, "out of memory");
                return MAGCAL_ERR_BUFFER_FULL;
            }
            buf = nb;
            cap = ncap;
        }
        got = fread(buf + len, 1u, cap - len, f);
        len += got;
        if (got == 0u) {
            break;
        }
    }
    if (ferror(f)) {
        free(buf);
        if (!is_stdin) {
            (void)fclose(f);
        }
        set_err(&cx, 0u, 0u, "read error");
        return MAGCAL_ERR_PORT;
    }
    if (!is_stdin) {
        (void)fclose(f);
    }
    st = magcal_replay_csv_parse(buf, len, cx.name, required, out, err, err_len);
    free(buf);
    return st;
}

/* ------------------------------------------------------------------ plane + fill */

magcal_status_t magcal_replay_csv_plane(const char *s, magcal_replay_plane_t *out)
{
    unsigned a, b;
    if (s == NULL || out == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (strlen(s) != 2u) {
        return MAGCAL_ERR_ARG;
    }
    a = (unsigned)(lower((unsigned char)s[0]) - 'x');
    b = (unsigned)(lower((unsigned char)s[1]) - 'x');
    if (a > 2u || b > 2u || a == b) {
        return MAGCAL_ERR_ARG;
    }
    out->src[0] = a;
    out->src[1] = b;
    out->src[2] = 3u - a - b;
    return MAGCAL_OK;
}

magcal_status_t magcal_replay_csv_fill(const magcal_replay_csv_t *d, size_t first, size_t count,
                                       size_t step, const magcal_replay_plane_t *plane,
                                       magcal_vec3_t *mag, magcal_vec3_t *accel, uint32_t *t_ms)
{
    static const magcal_replay_plane_t k_xy = {{0u, 1u, 2u}};
    size_t k, a;
    double t0 = 0.0, tprev = 0.0;
    if (d == NULL || mag == NULL) {
        return MAGCAL_ERR_NULL;
    }
    if (plane == NULL) {
        plane = &k_xy;
    }
    for (a = 0u; a < 3u; ++a) {
        if (plane->src[a] > 2u) {
            return MAGCAL_ERR_ARG;
        }
    }
    if (step == 0u || count == 0u || first >= d->n_rows ||
        (count - 1u) > (d->n_rows - 1u - first) / step) {
        return MAGCAL_ERR_ARG;
    }
    if (d->col[MAGCAL_REPLAY_COL_MX + plane->src[0]] == NULL ||
        d->col[MAGCAL_REPLAY_COL_MX + plane->src[1]] == NULL) {
        return MAGCAL_ERR_NO_DATA;
    }
    if (accel != NULL && (d->col[MAGCAL_REPLAY_COL_AX] == NULL ||
                          d->col[MAGCAL_REPLAY_COL_AY] == NULL ||
                          d->col[MAGCAL_REPLAY_COL_AZ] == NULL)) {
        return MAGCAL_ERR_NO_DATA;
    }
    if (t_ms != NULL) {
        if (d->col[MAGCAL_REPLAY_COL_T] == NULL) {
            return MAGCAL_ERR_NO_DATA;
        }
        t0 = d->col[MAGCAL_REPLAY_COL_T][first];
        tprev = t0;
    }
    for (k = 0u; k < count; ++k) {
        size_t r = first + k * step;
        float m[3] = {0.0f, 0.0f, 0.0f};
        float g[3] = {0.0f, 0.0f, 0.0f};
        for (a = 0u; a < 3u; ++a) {
            const double *cm = d->col[MAGCAL_REPLAY_COL_MX + plane->src[a]];
            double v = (cm != NULL) ? cm[r] : NAN;
            if (!isfinite(v)) {
                if (a < 2u) {
                    return MAGCAL_ERR_NONFINITE;
                }
                v = 0.0;
            }
            m[a] = (float)v;
            if (accel != NULL) {
                double w = d->col[MAGCAL_REPLAY_COL_AX + plane->src[a]][r];
                if (!isfinite(w)) {
                    return MAGCAL_ERR_NONFINITE;
                }
                g[a] = (float)w;
            }
        }
        mag[k].x = m[0];
        mag[k].y = m[1];
        mag[k].z = m[2];
        if (accel != NULL) {
            accel[k].x = g[0];
            accel[k].y = g[1];
            accel[k].z = g[2];
        }
        if (t_ms != NULL) {
            double t = d->col[MAGCAL_REPLAY_COL_T][r];
            double ms;
            if (!isfinite(t)) {
                return MAGCAL_ERR_NONFINITE;
            }
            if (t < tprev) {
                return MAGCAL_ERR_ARG;
            }
            tprev = t;
            ms = floor((t - t0) * 1000.0 + 0.5);
            if (ms > 4294967295.0) {
                return MAGCAL_ERR_ARG;
            }
            t_ms[k] = (uint32_t)ms;
        }
    }
    return MAGCAL_OK;
}
