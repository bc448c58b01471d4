/* Host-only CSV dump reader (see replay_csv.h). Every byte access is bounded by the buffer
 * length; every limit is checked before it can overflow. */
#include "replay_csv.h"

#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const char *const k_col_names[MAGCAL_REPLAY_COL_COUNT] = {
    "t", "mx", "my", "mz", "ax", "ay", "az", "heading_ref_deg", "cog_deg", "speed_mps", "glitch",
    "outlier"};

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
    if (!isfinite(x) || (errno == ERANGE && fabs(x) > 1.0)) {
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

static magcal_status_t parse_header(const ctx_t *cx, const char *p, size_t n, size_t line_no,
                                    uint32_t required, header_t *h, magcal_replay_csv_t *d)
{
    size_t nf = 1u, i, f = 0u, start = 0u;
    int seen[MAGCAL_REPLAY_COL_COUNT];
    for (i = 0u; i < n; ++i) {
        nf += (p[i] == ',') ? 1u : 0u;
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
        if (i == n || p[i] == ',') {
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
            set_err(cx, line_no, 0u, "missing required column \"%s\" in the header", k_col_names[i]);
            return MAGCAL_ERR_ARG;
        }
    }
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
        nf += (p[i] == ',') ? 1u : 0u;
    }
    if (nf != h->n_fields) {
        set_err(cx, line_no, (nf < h->n_fields ? nf : h->n_fields) + 1u,
                "row has %lu fields but the header has %lu%s", (unsigned long)nf,
                (unsigned long)h->n_fields, nf < h->n_fields ? " (truncated line?)" : "");
        return MAGCAL_ERR_ARG;
    }
    for (i = 0u; i <= n; ++i) {
        if (i == n || p[i] == ',') {
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
        float m[3], g[3];
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
