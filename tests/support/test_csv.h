/* Column reader for the tests that read ../shared recordings (host only: stdio). */
#ifndef MAGCAL_TEST_CSV_H
#define MAGCAL_TEST_CSV_H

#include <stddef.h>

/** Longest line test_read_csv accepts (a longer line fails the test). */
#define TEST_CSV_LINE_LEN 1024u

/**
 * Read the named columns of a CSV with one header line into out[row * ncols + k] (double; an
 * unparsable or missing cell is NaN, "nan" parses as NaN). The first n_required names must be
 * in the header (else the calling test fails); the others are optional and read as NaN when the
 * header lacks them. At most max_rows rows; a missing file fails the test. Returns the row count.
 */
size_t test_read_csv(const char *path, const char *const *names, size_t ncols, size_t n_required, double *out,
                     size_t max_rows);

#endif /* MAGCAL_TEST_CSV_H */
