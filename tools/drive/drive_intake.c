/*
 * magcal_drive_intake: feed a drive CSV (tools/gen_drive.py columns; docs/replay.md format) row by
 * row through a 2-D and a 3-D intake store and print, as one JSON object, what the stores did.
 *
 *   magcal_drive_intake [--range UT] [--only 2|3] DUMP.csv
 *
 * Per park (rows with parked = 1, consecutive): the bins newly filled during it (re-binning after a
 * centre change included), and the clean parked samples (glitch = disturbed = 0) stored during it
 * (added + replaced) with, in 2-D, their distinct 10-degree sectors around the store's centre. At the step row (first step = 1) and at
 * the end: coverage, centre, counters. Columns used: mx, my, mz (required), parked, step
 * (optional). Exit 0 on success, 2 on an unreadable file.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "magcal/intake.h"

#define LINE_MAX_LEN 1024
#define MAX_COLS 40

static magcal_intake_slot_t g_slots2[MAGCAL_INTAKE_SLOTS_2D(36u, 8u)];
static magcal_intake_slot_t g_slots3[MAGCAL_INTAKE_SLOTS_3D(10u, 4u)];
static magcal_intake_t g_s2;
static magcal_intake_t g_s3;

typedef struct {
    uint32_t mask[MAGCAL_INTAKE_MASK_WORDS(MAGCAL_INTAKE_CELLS_3D_MAX(10u))];
    magcal_intake_counters_t c;
} snap_t;

typedef struct {
    unsigned parks;
    unsigned max_new_bins; /* bins newly filled over a park (includes re-binning by a new centre) */
    unsigned max_stored;   /* parked samples stored (added or replaced) during one park */
    unsigned max_sectors;  /* 2-D: distinct 10-degree sectors of those samples around the centre */
    unsigned cur_stored;
    uint64_t cur_sectors;  /* bit set of the sectors of this park */
} park_stats_t;

static void take(const magcal_intake_t *st, snap_t *s)
{
    (void)magcal_intake_mask(st, s->mask, sizeof(s->mask) / sizeof(s->mask[0]));
    (void)magcal_intake_counters(st, &s->c);
}

static void park_end(const magcal_intake_t *st, const snap_t *at_start, park_stats_t *ps)
{
    snap_t now;
    unsigned w, nb = 0, stored;
    take(st, &now);
    for (w = 0; w < sizeof(now.mask) / sizeof(now.mask[0]); ++w) {
        uint32_t x = now.mask[w] & ~at_start->mask[w];
        while (x != 0u) {
            nb += x & 1u;
            x >>= 1u;
        }
    }
    stored = ps->cur_stored;
    {
        unsigned k, ns = 0;
        for (k = 0; k < 64; ++k) {
            ns += (unsigned)((ps->cur_sectors >> k) & 1u);
        }
        ps->max_sectors = (ns > ps->max_sectors) ? ns : ps->max_sectors;
    }
    ps->cur_stored = 0;
    ps->cur_sectors = 0;
    ps->parks++;
    ps->max_new_bins = (nb > ps->max_new_bins) ? nb : ps->max_new_bins;
    ps->max_stored = (stored > ps->max_stored) ? stored : ps->max_stored;
}

static void print_store(const char *name, const magcal_intake_t *st, const park_stats_t *ps, const char *tail)
{
    magcal_intake_progress_t p;
    magcal_intake_counters_t c;
    (void)magcal_intake_progress(st, &p);
    (void)magcal_intake_counters(st, &c);
    printf("\"%s\": {\"stored\": %u, \"bins\": %u, \"bins_filled\": %u, \"coverage_deg\": %.1f, "
           "\"completion_pct\": %.1f, \"centre\": [%.3f, %.3f, %.3f], \"radius\": %.3f, \"centre_source\": %d, "
           "\"pushed\": %u, \"added\": %u, \"replaced\": %u, \"refused_spacing\": %u, \"refused_saturated\": %u, "
           "\"refused_nonfinite\": %u, \"refused_level\": %u, \"rebinned\": %u, \"rebin_dropped\": %u, \"recentres\": %u",
           name, (unsigned)p.stored, (unsigned)p.bins, (unsigned)p.bins_filled, (double)p.coverage_deg,
           (double)p.completion_pct, (double)p.centre.x, (double)p.centre.y, (double)p.centre.z, (double)p.radius,
           (int)p.centre_source, (unsigned)c.pushed, (unsigned)c.added, (unsigned)c.replaced,
           (unsigned)c.refused_spacing, (unsigned)c.refused_saturated, (unsigned)c.refused_nonfinite, (unsigned)c.refused_level,
           (unsigned)c.rebinned, (unsigned)c.rebin_dropped, (unsigned)c.recentres);
    if (ps != NULL) {
        printf(", \"parks\": %u, \"park_max_new_bins\": %u, \"park_max_stored\": %u, \"park_max_sectors\": %u",
               ps->parks, ps->max_new_bins, ps->max_stored, ps->max_sectors);
    }
    printf("}%s", tail);
}

static int split(char *line, char **cols)
{
    int n = 0;
    char *p = line;
    while (n < MAX_COLS) {
        char *c = strchr(p, ',');
        cols[n++] = p;
        if (c == NULL) {
            break;
        }
        *c = '\0';
        p = c + 1;
    }
    return n;
}

int main(int argc, char **argv)
{
    magcal_intake_cfg_t c2 = MAGCAL_INTAKE_CFG_DEFAULT_2D;
    magcal_intake_cfg_t c3 = MAGCAL_INTAKE_CFG_DEFAULT_3D;
    char line[LINE_MAX_LEN];
    char *cols[MAX_COLS];
    int ix = -1, iy = -1, iz = -1, ipark = -1, istep = -1, iglitch = -1, idist = -1;
    int header = 0, in_park = 0, stepped = 0;
    const char *path = NULL;
    float range = 0.0f;
    int only = 0; /* 0: both stores, 2 or 3: that one only (for per-push instruction counts) */
    unsigned long rows = 0;
    snap_t p2, p3;
    park_stats_t ps2 = {0, 0, 0, 0, 0, 0}, ps3 = {0, 0, 0, 0, 0, 0};
    FILE *f;
    int i;
    for (i = 1; i < argc; ++i) {
        if (strcmp(argv[i], "--range") == 0 && i + 1 < argc) {
            range = strtof(argv[++i], NULL);
        } else if (strcmp(argv[i], "--only") == 0 && i + 1 < argc) {
            only = atoi(argv[++i]);
        } else {
            path = argv[i];
        }
    }
    if (path == NULL || (f = fopen(path, "r")) == NULL) {
        fprintf(stderr, "usage: magcal_drive_intake [--range UT] DUMP.csv\n");
        return 2;
    }
    c2.range_limit = range;
    c3.range_limit = range;
    if (magcal_intake_init(&g_s2, &c2, g_slots2, sizeof(g_slots2) / sizeof(g_slots2[0])) != MAGCAL_OK ||
        magcal_intake_init(&g_s3, &c3, g_slots3, sizeof(g_slots3) / sizeof(g_slots3[0])) != MAGCAL_OK) {
        fprintf(stderr, "init failed\n");
        fclose(f);
        return 2;
    }
    printf("{");
    while (fgets(line, sizeof(line), f) != NULL) {
        int n;
        line[strcspn(line, "\r\n")] = '\0';
        if (line[0] == '#' || line[0] == '\0') {
            continue;
        }
        n = split(line, cols);
        if (!header) {
            for (i = 0; i < n; ++i) {
                ix = (strcmp(cols[i], "mx") == 0) ? i : ix;
                iy = (strcmp(cols[i], "my") == 0) ? i : iy;
                iz = (strcmp(cols[i], "mz") == 0) ? i : iz;
                ipark = (strcmp(cols[i], "parked") == 0) ? i : ipark;
                istep = (strcmp(cols[i], "step") == 0) ? i : istep;
                iglitch = (strcmp(cols[i], "glitch") == 0) ? i : iglitch;
                idist = (strcmp(cols[i], "disturbed") == 0) ? i : idist;
            }
            if (ix < 0 || iy < 0 || iz < 0) {
                fprintf(stderr, "%s: no mx, my, mz columns\n", path);
                fclose(f);
                return 2;
            }
            header = 1;
            continue;
        }
        if (n <= ix || n <= iy || n <= iz) {
            fprintf(stderr, "%s: short row %lu\n", path, rows);
            fclose(f);
            return 2;
        }
        {
            const magcal_vec3_t m = {strtof(cols[ix], NULL), strtof(cols[iy], NULL), strtof(cols[iz], NULL)};
            const int parked = (ipark >= 0 && ipark < n) ? atoi(cols[ipark]) : 0;
            const int step = (istep >= 0 && istep < n) ? atoi(cols[istep]) : 0;
            const int clean = !((iglitch >= 0 && iglitch < n && atoi(cols[iglitch]) != 0) ||
                                (idist >= 0 && idist < n && atoi(cols[idist]) != 0));
            if (step && !stepped) {
                printf("\"step_row\": %lu, ", rows);
                print_store("at_step_2d", &g_s2, NULL, ", ");
                print_store("at_step_3d", &g_s3, NULL, ", ");
                stepped = 1;
            }
            if (parked && !in_park) {
                take(&g_s2, &p2);
                take(&g_s3, &p3);
            } else if (!parked && in_park) {
                park_end(&g_s2, &p2, &ps2);
                park_end(&g_s3, &p3, &ps3);
            }
            in_park = parked;
            {
                magcal_intake_outcome_t o2, o3;
                o2 = MAGCAL_INTAKE_REFUSED_SPACING;
                o3 = MAGCAL_INTAKE_REFUSED_SPACING;
                if (only != 3) {
                    (void)magcal_intake_push(&g_s2, &m, &o2);
                }
                if (only != 2) {
                    (void)magcal_intake_push(&g_s3, &m, &o3);
                }
                if (parked && clean && (o2 == MAGCAL_INTAKE_STORED || o2 == MAGCAL_INTAKE_REPLACED)) {
                    magcal_intake_progress_t p;
                    double a;
                    (void)magcal_intake_progress(&g_s2, &p);
                    a = atan2(-((double)m.x - (double)p.centre.x), (double)m.y - (double)p.centre.y) * 57.29577951308232;
                    a = (a < 0.0) ? a + 360.0 : a;
                    ps2.cur_stored++;
                    ps2.cur_sectors |= (uint64_t)1u << ((unsigned)(a / 10.0) % 36u);
                }
                if (parked && clean && (o3 == MAGCAL_INTAKE_STORED || o3 == MAGCAL_INTAKE_REPLACED)) {
                    ps3.cur_stored++;
                }
            }
        }
        rows++;
    }
    fclose(f);
    if (in_park) {
        park_end(&g_s2, &p2, &ps2);
        park_end(&g_s3, &p3, &ps3);
    }
    printf("\"rows\": %lu, ", rows);
    print_store("end_2d", &g_s2, &ps2, ", ");
    print_store("end_3d", &g_s3, &ps3, "}\n");
    return 0;
}
