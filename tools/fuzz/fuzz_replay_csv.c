/*
 * libFuzzer harness for the dump CSV reader (port/replay/replay_csv.c): arbitrary bytes are parsed
 * with and without required columns, and every accepted dump is converted with
 * magcal_replay_csv_fill() the way magcal-replay does.
 *
 * Invariants (abort = crash for libFuzzer):
 *  - the status is one the header documents for the call;
 *  - failure: out is empty (nothing to free) and the message is non-empty and NUL-terminated;
 *  - success: message "", n_rows >= 1, required columns present and non-missing, every value
 *    finite or NaN (missing), source lines strictly increasing;
 *  - fill(): documented status; on success the in-plane components are finite floats.
 */
#include <math.h>

#include "fuzz_common.h"
#include "replay_csv.h"

static int csv_parse_status_ok(magcal_status_t st)
{
    return st == MAGCAL_OK || st == MAGCAL_ERR_ARG || st == MAGCAL_ERR_NO_DATA ||
           st == MAGCAL_ERR_BUFFER_FULL;
}

static int csv_empty(const magcal_replay_csv_t *d)
{
    size_t c;
    for (c = 0u; c < (size_t)MAGCAL_REPLAY_COL_COUNT; ++c) {
        if (d->col[c] != NULL) {
            return 0;
        }
    }
    return d->line == NULL && d->n_rows == 0u;
}

static void csv_check_fill(const magcal_replay_csv_t *d)
{
    enum { FILL_MAX = 256 };
    magcal_vec3_t mag[FILL_MAX];
    magcal_vec3_t acc[FILL_MAX];
    uint32_t t_ms[FILL_MAX];
    size_t count = d->n_rows < (size_t)FILL_MAX ? d->n_rows : (size_t)FILL_MAX;
    size_t k;
    magcal_status_t st;

    st = magcal_replay_csv_fill(d, 0u, count, 1u, NULL, mag, NULL, NULL);
    FUZZ_CHECK(st == MAGCAL_OK || st == MAGCAL_ERR_NO_DATA || st == MAGCAL_ERR_NONFINITE,
               "fill(mag) status");
    if (st == MAGCAL_OK) {
        for (k = 0u; k < count; ++k) {
            FUZZ_CHECK(isfinite(mag[k].x) && isfinite(mag[k].y), "fill: in-plane field not finite");
        }
    }
    st = magcal_replay_csv_fill(d, 0u, count, 1u, NULL, mag, acc, t_ms);
    FUZZ_CHECK(st == MAGCAL_OK || st == MAGCAL_ERR_NO_DATA || st == MAGCAL_ERR_NONFINITE ||
                   st == MAGCAL_ERR_ARG,
               "fill(mag, accel, t) status");
    if (st == MAGCAL_OK) {
        for (k = 1u; k < count; ++k) {
            FUZZ_CHECK(t_ms[k] >= t_ms[k - 1u], "fill: time decreases");
        }
    }
}

static void csv_one(const uint8_t *data, size_t size, uint32_t required)
{
    magcal_replay_csv_t d;
    char err[MAGCAL_REPLAY_CSV_ERR_LEN];
    magcal_status_t st;
    size_t c, r;

    memset(&d, 0xA5, sizeof d); /* garbage: the parser must not read or free it */
    memset(err, 'x', sizeof err);
    st = magcal_replay_csv_parse((const char *)data, size, "fuzz.csv", required, &d, err, sizeof err);
    FUZZ_CHECK(csv_parse_status_ok(st), "parse status");
    FUZZ_CHECK(memchr(err, '\0', sizeof err) != NULL, "message not terminated");
    if (st != MAGCAL_OK) {
        FUZZ_CHECK(csv_empty(&d), "failed parse left data behind");
        FUZZ_CHECK(err[0] != '\0', "failure without a message");
        return;
    }
    FUZZ_CHECK(err[0] == '\0', "success with a message");
    FUZZ_CHECK(d.n_rows >= 1u && d.line != NULL, "success without rows");
    for (r = 1u; r < d.n_rows; ++r) {
        FUZZ_CHECK(d.line[r] > d.line[r - 1u], "source lines not increasing");
    }
    for (c = 0u; c < (size_t)MAGCAL_REPLAY_COL_COUNT; ++c) {
        int req = (required & MAGCAL_REPLAY_COL_BIT(c)) != 0u;
        if (req) {
            FUZZ_CHECK(d.col[c] != NULL, "required column absent");
        }
        if (d.col[c] == NULL) {
            continue;
        }
        for (r = 0u; r < d.n_rows; ++r) {
            double v = d.col[c][r];
            FUZZ_CHECK(isfinite(v) || isnan(v), "infinite value accepted");
            FUZZ_CHECK(!req || !isnan(v), "required cell missing");
        }
    }
    csv_check_fill(&d);
    magcal_replay_csv_free(&d);
    FUZZ_CHECK(csv_empty(&d), "free left pointers");
    magcal_replay_csv_free(&d); /* documented safe twice */
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    csv_one(data, size, 0u);
    csv_one(data, size,
            MAGCAL_REPLAY_COL_BIT(MAGCAL_REPLAY_COL_MX) | MAGCAL_REPLAY_COL_BIT(MAGCAL_REPLAY_COL_MY));
    return 0;
}
