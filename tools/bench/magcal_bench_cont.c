/*
 * Host (x86-64, callgrind) equivalent of the M4F per-solve count of cont.elf (m4f_image/main_cont.c):
 * the continuous calibrator at MAGCAL_CONT_CFG_DEFAULT fed a drive CSV row by row (push + step +
 * heading), and the step calls of its FIRST ADOPTED solve (from the step that starts it to the one
 * that ends it) made through bench_cont_collect_step(), the function run_bench.py toggles callgrind
 * on:
 *
 *     valgrind --tool=callgrind --toggle-collect=bench_cont_collect_step \
 *         magcal_bench_cont DRIVE.csv RANGE [REPS]
 *
 * Two passes over the same rows (the library is deterministic): the first finds the rows of that
 * solve, the second repeats the stream and routes exactly those steps through the toggled
 * function, then stops. Columns t (s), mx, my, mz by name; '#' lines skipped; RANGE is the
 * sensor's declared range (intake cfg.range_limit, 0 = undeclared); REPS repeats the rows (stamps
 * shifted by the drive's period), as cont.elf does. Prints "CONT_HOST rows_fed start end steps
 * outcome" and exits 0, or 1 when the drive has no adopted solve or a file error.
 */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "magcal/continuous.h"

#define SLOTS MAGCAL_CONT_SLOTS(36u, 8u)
#define MAX_ROWS 400000u

static magcal_intake_slot_t g_slots[SLOTS];
static magcal_vec2_t g_buf[SLOTS];
static MAGCAL_CALIBRATOR_WORKSPACE_DECLARE(g_work, SLOTS);
static magcal_cont_t g_cc;
static magcal_vec3_t g_m[MAX_ROWS];
static uint32_t g_t[MAX_ROWS];

/* The toggled function: one step of the measured solve. */
__attribute__((noinline)) magcal_cont_outcome_t bench_cont_collect_step(magcal_cont_t *cc);
__attribute__((noinline)) magcal_cont_outcome_t bench_cont_collect_step(magcal_cont_t *cc)
{
    return magcal_cont_step(cc);
}

static int col_of(char *hdr, const char *name)
{
    int k = 0;
    char *tok = strtok(hdr, ",\r\n");
    while (tok != NULL) {
        if (strcmp(tok, name) == 0) {
            return k;
        }
        tok = strtok(NULL, ",\r\n");
        k++;
    }
    return -1;
}

static size_t load(const char *path)
{
    static char line[4096], hdr[4096];
    FILE *f = fopen(path, "r");
    int ix[4] = {-1, -1, -1, -1};
    static const char *const names[4] = {"t", "mx", "my", "mz"};
    size_t n = 0u;
    double t0 = 0.0;
    int k;
    if (f == NULL) {
        return 0u;
    }
    while (fgets(line, sizeof line, f) != NULL && line[0] == '#') {
    }
    for (k = 0; k < 4; ++k) {
        memcpy(hdr, line, sizeof hdr);
        ix[k] = col_of(hdr, names[k]);
    }
    if (ix[0] < 0 || ix[1] < 0 || ix[2] < 0 || ix[3] < 0) {
        fclose(f);
        return 0u;
    }
    while (n < MAX_ROWS && fgets(line, sizeof line, f) != NULL) {
        double v[4] = {0.0, 0.0, 0.0, 0.0};
        char *p = line;
        int c = 0;
        if (line[0] == '#') {
            continue;
        }
        while (p != NULL) {
            for (k = 0; k < 4; ++k) {
                if (c == ix[k]) {
                    v[k] = strtod(p, NULL);
                }
            }
            p = strchr(p, ',');
            p = p != NULL ? p + 1 : NULL;
            c++;
        }
        if (n == 0u) {
            t0 = v[0];
        }
        g_t[n] = (uint32_t)((v[0] - t0) * 1000.0 + 0.5);
        g_m[n].x = (float)v[1];
        g_m[n].y = (float)v[2];
        g_m[n].z = (float)v[3];
        n++;
    }
    fclose(f);
    return n;
}

/* One pass; collect = 0: find the first adopted solve's rows; 1: route them through the toggle. */
static int pass(size_t n, uint32_t reps, uint32_t period, float range, int collect, uint32_t *s0,
                uint32_t *s1, uint32_t *steps)
{
    magcal_cont_cfg_t cfg = MAGCAL_CONT_CFG_DEFAULT;
    uint32_t r, row = 0u, start = 0u, cnt = 0u;
    int in_solve = 0;
    cfg.intake.range_limit = range;
    if (magcal_cont_init(&g_cc, &cfg, NULL, g_slots, SLOTS, g_buf, g_work, sizeof g_work) != MAGCAL_OK) {
        return -1;
    }
    for (r = 0u; r < reps; ++r) {
        size_t i;
        for (i = 0u; i < n; ++i, ++row) {
            magcal_cont_heading_t hd;
            magcal_cont_outcome_t o;
            (void)magcal_cont_push(&g_cc, &g_m[i], g_t[i] + r * period);
            if (collect && row >= *s0 && row <= *s1) {
                o = bench_cont_collect_step(&g_cc);
            } else {
                o = magcal_cont_step(&g_cc);
            }
            (void)magcal_cont_heading(&g_cc, &g_m[i], 0.0f, &hd);
            if (o == MAGCAL_CONT_IN_PROGRESS && !in_solve) {
                in_solve = 1;
                start = row;
                cnt = 0u;
            }
            cnt += in_solve ? 1u : 0u;
            if (in_solve && o != MAGCAL_CONT_IN_PROGRESS) {
                in_solve = 0;
                if (o == MAGCAL_CONT_ADOPTED) {
                    if (collect && (start != *s0 || row != *s1)) {
                        return -2; /* the second pass did not repeat the first */
                    }
                    *s0 = start;
                    *s1 = row;
                    *steps = cnt;
                    return (int)row + 1;
                }
            }
        }
    }
    return 0;
}

int main(int argc, char **argv)
{
    size_t n;
    uint32_t reps = 1u, period, s0 = 0u, s1 = 0u, steps = 0u;
    float range;
    int fed;
    if (argc < 3 || argc > 4) {
        fprintf(stderr, "usage: magcal_bench_cont DRIVE.csv RANGE [REPS]\n");
        return 1;
    }
    range = (float)strtod(argv[2], NULL);
    if (argc == 4) {
        reps = (uint32_t)strtoul(argv[3], NULL, 10);
    }
    n = load(argv[1]);
    if (n < 2u || reps < 1u) {
        fprintf(stderr, "magcal_bench_cont: no rows in %s\n", argv[1]);
        return 1;
    }
    period = g_t[n - 1u] + (g_t[n - 1u] - g_t[0]) / (uint32_t)(n - 1u);
    fed = pass(n, reps, period, range, 0, &s0, &s1, &steps);
    if (fed <= 0) {
        fprintf(stderr, "magcal_bench_cont: no adopted solve in %s\n", argv[1]);
        return 1;
    }
    fed = pass(n, reps, period, range, 1, &s0, &s1, &steps);
    if (fed <= 0) {
        fprintf(stderr, "magcal_bench_cont: the second pass differed (%d)\n", fed);
        return 1;
    }
    printf("CONT_HOST %d %lu %lu %lu adopted\n", fed, (unsigned long)s0, (unsigned long)s1, (unsigned long)steps);
    return 0;
}
