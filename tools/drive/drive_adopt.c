/*
 * magcal_drive_adopt: diagnosis of the continuous 2-D calibrator's adoptions on a drive dump
 * (tools/gen_drive.py), for tools/drive/adopt_truth.py.
 *
 *   magcal_drive_adopt [--no-tilt] [--range R] [--trace N] [--arc COV [--arc-tol DEG]
 *                      [--arc-model DEG]] [--arc-refit COV] DUMP.csv > OUT.jsonl
 *
 * Runs the loop of `magcal-replay --stream` (2-D, default configuration, one push and one step
 * per row; magcal_cont_push_g with the dump's ax, ay, az in g unless --no-tilt) and prints one JSON
 * object per line:
 *  - {"solve": ...}: every finished solve: the row, the outcome, the status, the calibration in
 *    force after it, and the store the solve saw (captured when its snapshot completed): every
 *    stored sample's raw x, y, z, its level bit and whether the solve kept it as an inlier;
 *    for an adopting solve also the calibrations the batch solver (magcal_calibrator_run, the
 *    same configuration, no installed calibration) fits on that snapshot (`refit_all`) and on
 *    its LEVEL samples only (`refit_level`);
 *    every solve also reports the arc stage's fields (arc, arc_bound = its est_param_err_deg:
 *    calibrator.h "Arc stage"), its estimates and counts, and `cand`, the calibration it fitted (adopted or not);
 *    --arc COV / --arc-tol / --arc-model set the continuous calibrator's arc stage (cfg.arc_*:
 *    --arc-tol 0.001 scores every arc solve and refuses it, so the loop keeps collecting);
 *    --arc-refit COV: every solve's snapshot is also refitted by the batch solver with the arc
 *    stage on (no tolerance, no model term) on all its samples (`arc_all`) and on its level
 *    samples only (`arc_level`);
 *  - {"change": row}: a change declared;
 *  - {"trace": row, ...} every N rows (--trace N): live progress, the store's centre and radius.
 * The truth side (the true heading error of each calibration, the share of tilted samples) is
 * computed by adopt_truth.py from the dump's truth columns.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "magcal/continuous.h"
#include "replay_csv.h"

#define DA_SLOTS MAGCAL_CONT_SLOTS(36u, 8u)

static magcal_intake_slot_t g_slots[DA_SLOTS];
static magcal_vec2_t g_buf[DA_SLOTS];
static MAGCAL_CALIBRATOR_WORKSPACE_DECLARE(g_work, DA_SLOTS);
static magcal_cont_t g_cc;

/* the store at the last completed snapshot */
static magcal_vec3_t g_snap_m[DA_SLOTS];
static int g_snap_lv[DA_SLOTS];
static size_t g_snap_n;

/* offline refits */
static magcal_vec2_t g_rbuf[DA_SLOTS];
static MAGCAL_CALIBRATOR_WORKSPACE_DECLARE(g_rwork, DA_SLOTS);
static magcal_calibrator_t g_rcal;
static float g_arc_refit; /* --arc-refit COV: every solve's snapshot refitted with the arc stage */

static void capture_store(const magcal_intake_t *st)
{
    uint32_t b, k;
    g_snap_n = 0u;
    for (b = 0u; b < st->n_bins; ++b) {
        for (k = 0u; k < st->count[b]; ++k) {
            const magcal_intake_slot_t *s = &st->slots[b * st->cfg.per_bin + k];
            g_snap_m[g_snap_n] = s->m;
            g_snap_lv[g_snap_n] = (int)((s->seq >> 31) & 1u);
            g_snap_n++;
        }
    }
}

/* A JSON number, null when not finite. */
static void print_num(double v)
{
    if (isfinite(v)) {
        printf("%.4g", v);
    } else {
        fputs("null", stdout);
    }
}

static void print_cal(const char *key, const magcal_cal2d_t *c)
{
    printf(",\"%s\":{\"offset\":[%.6g,%.6g],\"m\":[[%.7g,%.7g],[%.7g,%.7g]],\"radius\":%.6g}", key,
           (double)c->offset.x, (double)c->offset.y, (double)c->m[0][0], (double)c->m[0][1], (double)c->m[1][0],
           (double)c->m[1][1], (double)c->radius);
}

/* The batch solver on the captured snapshot (level_only: its level samples); prints the result.
 * arc > 0: with the arc stage on at that coverage (no tolerance, no model term: the bound is only
 * reported; the private fields magcal_calibrator_set_arc sets, calibrator_internal.h). */
static void refit(const char *key, int level_only, float arc)
{
    const magcal_calibrator_cfg_t cfg = MAGCAL_CALIBRATOR_CFG_STORE_DEFAULT;
    magcal_cal2d_t cur = MAGCAL_CAL2D_IDENTITY;
    magcal_cal_report_t rep;
    magcal_status_t s;
    size_t i, n = 0u;
    if (magcal_calibrator_init(&g_rcal, &cfg, g_rbuf, DA_SLOTS, g_rwork, sizeof g_rwork) != MAGCAL_OK) {
        return;
    }
    g_rcal.arc_min_cov = arc;
    g_rcal.arc_max_err = arc > 0.0f ? 1.0e9f : 0.0f;
    g_rcal.arc_model = 0.0f;
    for (i = 0u; i < g_snap_n; ++i) {
        if (level_only == 0 || g_snap_lv[i] != 0) {
            magcal_vec2_t p;
            p.x = g_snap_m[i].x;
            p.y = g_snap_m[i].y;
            (void)magcal_calibrator_push(&g_rcal, p);
            n++;
        }
    }
    s = magcal_calibrator_run(&g_rcal, &cur, &rep);
    printf(",\"%s\":{\"n\":%zu,\"status\":\"%s\",\"est_err\":", key, n, magcal_status_str(s));
    print_num((double)rep.est_heading_err_deg);
    printf(",\"coverage\":%.1f,\"arc\":%u,\"arc_bound\":", (double)rep.coverage_deg, (unsigned)rep.arc);
    print_num(rep.arc != 0u ? (double)rep.est_param_err_deg : NAN);
    if (s == MAGCAL_OK) {
        print_cal("cal", &cur);
    }
    print_cal("cand", &rep.cal);
    putchar('}');
}

static void print_solve(size_t row, magcal_cont_outcome_t oc)
{
    size_t i;
    printf("{\"solve\":%zu,\"outcome\":%d,\"status\":\"%s\",\"coarse\":%u,\"coverage\":%.1f,\"est_err\":",
           row, (int)oc, magcal_status_str(g_cc.last.status), (unsigned)g_cc.cal_coarse, (double)g_cc.last.coverage_deg);
    print_num((double)g_cc.last.est_heading_err_deg);
    printf(",\"arc\":%u,\"arc_bound\":", (unsigned)g_cc.last.arc);
    print_num(g_cc.last.arc != 0u ? (double)g_cc.last.est_param_err_deg : NAN);
    fputs(",\"noise\":", stdout);
    print_num((double)g_cc.last.est_noise_deg);
    fputs(",\"param\":", stdout);
    print_num((double)g_cc.last.est_param_err_deg);
    fputs(",\"design\":", stdout);
    print_num((double)g_cc.last.design_factor);
    printf(",\"used\":%u,\"rej_cons\":%u,\"resc_cons\":%u,\"rej_filter\":%u", (unsigned)g_cc.last.used,
           (unsigned)g_cc.last.rejected_consensus, (unsigned)g_cc.last.rescued_consensus,
           (unsigned)g_cc.last.rejected_filter);
    print_cal("cand", &g_cc.last.cal);
    print_cal("cal", &g_cc.cal);
    printf(",\"tilt_k\":%.5g,\"tilt_ok\":%u,\"tilt_pairs\":%u,\"tilt_s\":[%.5g,%.5g,%.5g],\"store_centre\":[%.4g,%.4g],\"store_radius\":%.4g,"
           "\"store_source\":%u",
           (double)g_cc.tc_k, (unsigned)g_cc.tc_ok, (unsigned)g_cc.tc_n, (double)g_cc.tc_s[0], (double)g_cc.tc_s[1],
           (double)g_cc.tc_s[2], (double)g_cc.store.centre.x,
           (double)g_cc.store.centre.y, (double)g_cc.store.radius, (unsigned)g_cc.store.centre_source);
    printf(",\"store\":[");
    for (i = 0u; i < g_snap_n; ++i) {
        int inl = -1;
        if (magcal_calibrator_inlier(&g_cc.solver, i, &inl) != MAGCAL_OK) {
            inl = -1;
        }
        printf("%s[%.9g,%.9g,%.9g,%d,%d]", i ? "," : "", (double)g_snap_m[i].x, (double)g_snap_m[i].y,
               (double)g_snap_m[i].z, g_snap_lv[i], inl);
    }
    putchar(']');
    if (oc == MAGCAL_CONT_ADOPTED) {
        refit("refit_all", 0, 0.0f);
        refit("refit_level", 1, 0.0f);
    }
    if (g_arc_refit > 0.0f) {
        refit("arc_all", 0, g_arc_refit);
        refit("arc_level", 1, g_arc_refit);
    }
    puts("}");
}

int main(int argc, char **argv)
{
    magcal_replay_csv_t d;
    char err[MAGCAL_REPLAY_CSV_ERR_LEN];
    magcal_cont_cfg_t cfg = MAGCAL_CONT_CFG_DEFAULT;
    const char *path = NULL;
    int no_tilt = 0;
    unsigned long trace = 0u;
    int a;
    size_t i;
    for (a = 1; a < argc; ++a) {
        if (strcmp(argv[a], "--no-tilt") == 0) {
            no_tilt = 1;
        } else if (strcmp(argv[a], "--trace") == 0 && a + 1 < argc) {
            trace = strtoul(argv[++a], NULL, 10);
        } else if (strcmp(argv[a], "--arc") == 0 && a + 1 < argc) {
            cfg.arc_coverage_deg = strtof(argv[++a], NULL); /* arc stage on (continuous.h) */
        } else if (strcmp(argv[a], "--arc-refit") == 0 && a + 1 < argc) {
            g_arc_refit = strtof(argv[++a], NULL);
        } else if (strcmp(argv[a], "--arc-tol") == 0 && a + 1 < argc) {
            cfg.arc_max_err_deg = strtof(argv[++a], NULL);
        } else if (strcmp(argv[a], "--arc-model") == 0 && a + 1 < argc) {
            cfg.arc_model_deg = strtof(argv[++a], NULL);
        } else if (strcmp(argv[a], "--range") == 0 && a + 1 < argc) {
            cfg.intake.range_limit = strtof(argv[++a], NULL);
        } else {
            path = argv[a];
        }
    }
    if (path == NULL) {
        fputs("usage: magcal_drive_adopt [--no-tilt] [--range R] [--trace N] [--arc COV [--arc-tol DEG] [--arc-model DEG]] [--arc-refit COV] DUMP.csv\n",
              stderr);
        return 1;
    }
    memset(&d, 0, sizeof d);
    if (magcal_replay_csv_read(path, MAGCAL_REPLAY_COL_BIT(MAGCAL_REPLAY_COL_MX) | MAGCAL_REPLAY_COL_BIT(MAGCAL_REPLAY_COL_MY),
                               &d, err, sizeof err) != MAGCAL_OK) {
        fprintf(stderr, "magcal_drive_adopt: %s\n", err);
        return 2;
    }
    if (magcal_cont_init(&g_cc, &cfg, NULL, g_slots, DA_SLOTS, g_buf, g_work, sizeof g_work) != MAGCAL_OK) {
        magcal_replay_csv_free(&d);
        return 3;
    }
    if (d.col[MAGCAL_REPLAY_COL_AX] == NULL || d.col[MAGCAL_REPLAY_COL_AY] == NULL || d.col[MAGCAL_REPLAY_COL_AZ] == NULL) {
        no_tilt = 1;
    }
    for (i = 0u; i < d.n_rows; ++i) {
        magcal_vec3_t m;
        const uint32_t t_ms = d.col[MAGCAL_REPLAY_COL_T] != NULL
                                  ? (uint32_t)(int64_t)llround((d.col[MAGCAL_REPLAY_COL_T][i] - d.col[MAGCAL_REPLAY_COL_T][0]) * 1000.0)
                                  : (uint32_t)(i * 20u);
        const double mz = d.col[MAGCAL_REPLAY_COL_MZ] != NULL ? d.col[MAGCAL_REPLAY_COL_MZ][i] : 0.0;
        const uint8_t stage0 = g_cc.stage;
        magcal_cont_outcome_t oc;
        m.x = (float)d.col[MAGCAL_REPLAY_COL_MX][i];
        m.y = (float)d.col[MAGCAL_REPLAY_COL_MY][i];
        m.z = isfinite(mz) ? (float)mz : 0.0f;
        if (no_tilt == 0) {
            magcal_vec3_t g;
            g.x = (float)d.col[MAGCAL_REPLAY_COL_AX][i];
            g.y = (float)d.col[MAGCAL_REPLAY_COL_AY][i];
            g.z = (float)d.col[MAGCAL_REPLAY_COL_AZ][i];
            (void)magcal_cont_push_g(&g_cc, &m, &g, t_ms);
        } else {
            (void)magcal_cont_push(&g_cc, &m, t_ms);
        }
        oc = magcal_cont_step(&g_cc);
        if (stage0 != 2u && g_cc.stage == 2u) {
            capture_store(&g_cc.store); /* the snapshot completed: the store the solve sees */
        }
        if (oc == MAGCAL_CONT_ADOPTED || oc == MAGCAL_CONT_REFUSED || oc == MAGCAL_CONT_FAILED) {
            print_solve(i, oc);
        } else if (oc == MAGCAL_CONT_CHANGE) {
            printf("{\"change\":%zu}\n", i);
        } else {
            /* idle, in progress */
        }
        if (trace > 0u && i % trace == 0u) {
            magcal_cont_progress_t p;
            (void)magcal_cont_progress(&g_cc, &p);
            printf("{\"trace\":%zu,\"coverage\":%.0f,\"stored\":%u,\"new\":%u,\"source\":%u,\"centre\":[%.4g,%.4g],"
                   "\"radius\":%.4g,\"recentres\":%u,\"rebinning\":%u,\"solves\":%u,\"stage\":%u,\"tilt_k\":%.4g,"
                   "\"tilt_ok\":%u}\n",
                   i, (double)p.coverage_deg, (unsigned)p.stored, (unsigned)p.new_since_solve,
                   (unsigned)g_cc.store.centre_source, (double)g_cc.store.centre.x, (double)g_cc.store.centre.y,
                   (double)g_cc.store.radius, (unsigned)g_cc.store.ctr.recentres, (unsigned)g_cc.store.rebin_pending,
                   (unsigned)g_cc.solves, (unsigned)g_cc.stage, (double)g_cc.tc_k, (unsigned)g_cc.tc_ok);
        }
    }
    magcal_replay_csv_free(&d);
    return 0;
}
