#include "test_csv.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "unity.h"

#define TEST_CSV_MAX_COLS 32

size_t test_read_csv(const char *path, const char *const *names, size_t ncols, size_t n_required, double *out,
                     size_t max_rows)
{
    char line[TEST_CSV_LINE_LEN];
    int idx[TEST_CSV_MAX_COLS];
    FILE *f = fopen(path, "r");
    size_t k;
    size_t n = 0u;
    TEST_ASSERT_NOT_NULL_MESSAGE(f, path);
    TEST_ASSERT_TRUE(ncols <= TEST_CSV_MAX_COLS);
    TEST_ASSERT_NOT_NULL(fgets(line, sizeof line, f));
    for (k = 0u; k < ncols; ++k) { /* header: position of each wanted column */
        const char *p = line;
        const size_t len = strlen(names[k]);
        int c = 0;
        idx[k] = -1;
        while (p != NULL) {
            if (strncmp(p, names[k], len) == 0 && (p[len] == ',' || p[len] == '\r' || p[len] == '\n' || p[len] == '\0')) {
                idx[k] = c;
                break;
            }
            p = strchr(p, ',');
            p = (p != NULL) ? p + 1 : NULL;
            ++c;
        }
        TEST_ASSERT_TRUE_MESSAGE(idx[k] >= 0 || k >= n_required, names[k]);
    }
    while (n < max_rows && fgets(line, sizeof line, f) != NULL) {
        const char *p = line;
        int c = 0;
        TEST_ASSERT_NOT_NULL_MESSAGE(strchr(line, '\n'), "line longer than TEST_CSV_LINE_LEN");
        for (k = 0u; k < ncols; ++k) {
            out[n * ncols + k] = NAN;
        }
        while (p != NULL && *p != '\0') {
            char *end;
            double v = strtod(p, &end);
            if (end == p) {
                v = NAN;
            }
            for (k = 0u; k < ncols; ++k) {
                if (idx[k] == c) {
                    out[n * ncols + k] = v;
                }
            }
            p = strchr(p, ',');
            p = (p != NULL) ? p + 1 : NULL;
            ++c;
        }
        ++n;
    }
    fclose(f);
    return n;
}
