/* magcal-replay: the 3-D, aided and swing parts (docs/replay.md, "Modes" and "Compass swing"),
 * kept apart from the CLI like replay_cal.h. Host tool: malloc is allowed here. */
#ifndef MAGCAL_REPLAY_MODES_H
#define MAGCAL_REPLAY_MODES_H

#include <stddef.h>

#include "magcal/ellipsoid.h"
#include "magcal/errmodel.h"
#include "magcal/swing.h"
#include "replay_csv.h"
#include "replay_report.h"

/** 3-D pipeline on n mapped samples: the OPTICS density stage (magcal_optics_filter3; filter
 *  "optics" or "optics-classic", automatic parameters unless eps > 0 / min_pts > 0; "none" skips
 *  it, as does n > MAGCAL_MAX_SAMPLES, with a note) on the samples, then the ellipsoid fit (AUTO
 *  model: quadric, sphere on poor coverage, residual gate) on its inliers. Fills r's 3-D fields,
 *  status and reason; on success *fit is the library result (its final outlier gate included)
 *  and flags[0..n) the per-sample outlier mask: 1 = rejected by the density stage or by the fit's
 *  gate (magcal_ellipsoid_outliers, checked to count res.n_rejected). Returns REPLAY_EXIT_OK,
 *  _CAL_FAILED or _INTERNAL. */
int replay_fit_3d(const magcal_vec3_t *m, size_t n, const char *filter, double eps, long min_pts,
                  replay_report_t *r, magcal_ellipsoid_result_t *fit, unsigned char *flags);

/** The 3-D fit's final outlier gate applied to one sample (rows outside the calibration):
 *  1 outlier, 0 kept, 0 when the sample cannot be judged (non-finite). */
int replay_classify_3d(const magcal_ellipsoid_result_t *fit, const magcal_vec3_t *m);

/** A fitted heading-deviation model (swing or adaptive Fourier). */
typedef struct {
    int ok;      /* 1 when fitted */
    int fourier; /* 0: swing (smith), 1: errmodel Fourier */
    magcal_swing_model_t swing;
    magcal_errmodel_t fmodel;
} replay_swing_t;

/**
 * Fit the deviation model on rows [first, end) where psi_c_deg (measured magnetic heading) and
 * psi_ref_deg (reference MAGNETIC heading) are both finite. Fills r->swing_* (status included;
 * a failed fit is reported, not an error). Returns REPLAY_EXIT_OK or REPLAY_EXIT_INTERNAL.
 */
int replay_swing_fit(const double *psi_c_deg, const double *psi_ref_deg, size_t first, size_t end,
                     int fourier, replay_report_t *r, replay_swing_t *sw);

/** Corrected magnetic heading in [0, 360), or NaN (input NaN or no model). */
double replay_swing_apply(const replay_swing_t *sw, double psi_c_deg);

/** Options of the aided mode. */
typedef struct {
    double unit_per_nt; /* dump field unit per nT (uT: 1e-3, gauss: 1e-5, nT: 1) */
    int igrf;           /* 1: IGRF-14 (1900.0-2030.0), 0: WMM2025 (2025.0-2030.0) */
    double year;        /* NaN: from the decimal_year column, else t as Unix time */
} replay_aided_opts_t;

/** Per-row gate outcome of the aided run (the headings CSV's `gate` column). */
enum {
    REPLAY_GATE_NOT_CAL = 0xFF, /* row outside the calibration range: never offered */
    REPLAY_GATE_SKIPPED = 0xFE  /* calibration row not fed (missing cell) or refused by the estimator */
    /* else a magcal_aided_gate_t: NONE (accepted), DOP, RAW, FIELD, VECTOR */
};

/** Name of a per-row gate outcome: none, dop, raw, field, vector, skipped, or "" (not offered). */
const char *replay_gate_name(unsigned char g);

/**
 * Read a prior calibration from a JSON report of an earlier `--mode 3d` or `--mode aided` run
 * (keys "matrix": 3x3 G, row-major, "offset": [x, y, z] V; both in that dump's field unit). When
 * the file names its unit (top-level "field_unit" or "aided": {"field_unit": ...}: uT, nT, gauss)
 * and it differs from the current dump's (unit_per_nt), V is converted (G is a ratio of equal
 * units and is kept). A 3d report ("mode": "3d") maps the field to its own magnitude "field"
 * (det G = 1), not to the reference field: when field_ref (|B_ref| in the dump unit) is finite,
 * G is scaled by field_ref / field; *g_scale returns the factor applied (1: none).
 * Returns REPLAY_EXIT_OK, or REPLAY_EXIT_INPUT with a message naming the file in err (unreadable,
 * not JSON, key missing or malformed, non-finite, singular G).
 */
int replay_read_prior(const char *path, double unit_per_nt, double field_ref, magcal_ellipsoid_cal_t *prior,
                      double *g_scale, char *err, size_t err_len);

/**
 * Per row: the WMM2025 (or IGRF-14, o->igrf) reference field (NED, dump unit) and declination from lat/lon/height and
 * the epoch. Rows where a cell is missing or the model rejects the input get NaN. Returns
 * REPLAY_EXIT_OK, or REPLAY_EXIT_INPUT with a message in err (no epoch source, date outside WMM).
 */
int replay_wmm_rows(const magcal_replay_csv_t *d, const replay_aided_opts_t *o, double *b_ned3,
                    double *decl_deg, char *err, size_t err_len);

/**
 * Feed rows [first, end) to magcal_aided_update (mapped field m, INS attitude columns, b_ned3,
 * dop column or 0; prior: cfg.prior, NULL = the default identity), read the estimate, fill r's
 * aided fields; gate_row[i] (n_rows entries) = per-row outcome (REPLAY_GATE_*, magcal_aided_gate_t).
 * Returns REPLAY_EXIT_OK (an estimate exists: OK, UNOBSERVABLE or NOT_CONVERGED),
 * REPLAY_EXIT_CAL_FAILED (no estimate), REPLAY_EXIT_INPUT (the estimator refuses the prior) or
 * REPLAY_EXIT_INTERNAL.
 */
int replay_aided_run(const magcal_replay_csv_t *d, const magcal_vec3_t *m, const double *b_ned3,
                     size_t first, size_t end, const magcal_ellipsoid_cal_t *prior, replay_report_t *r,
                     magcal_ellipsoid_cal_t *cal, unsigned char *gate_row);

#endif
