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

/** Fit the 3-D ellipsoid (AUTO model: quadric, sphere on poor coverage) to n mapped samples and
 *  fill r's 3-D fields, status and reason. Returns REPLAY_EXIT_OK, _CAL_FAILED or _INTERNAL. */
int replay_fit_3d(const magcal_vec3_t *m, size_t n, replay_report_t *r, magcal_ellipsoid_cal_t *cal);

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
    double year;        /* NaN: from the decimal_year column, else t as Unix time */
} replay_aided_opts_t;

/**
 * Per row: the WMM2025 reference field (NED, dump unit) and declination from lat/lon/height and
 * the epoch. Rows where a cell is missing or the model rejects the input get NaN. Returns
 * REPLAY_EXIT_OK, or REPLAY_EXIT_INPUT with a message in err (no epoch source, date outside WMM).
 */
int replay_wmm_rows(const magcal_replay_csv_t *d, const replay_aided_opts_t *o, double *b_ned3,
                    double *decl_deg, char *err, size_t err_len);

/**
 * Feed rows [first, end) to magcal_aided_update (mapped field m, INS attitude columns, b_ned3,
 * dop column or 0), read the estimate, fill r's aided fields. Returns REPLAY_EXIT_OK (an estimate
 * exists: OK, UNOBSERVABLE or NOT_CONVERGED), REPLAY_EXIT_CAL_FAILED (no estimate) or
 * REPLAY_EXIT_INTERNAL.
 */
int replay_aided_run(const magcal_replay_csv_t *d, const magcal_vec3_t *m, const double *b_ned3,
                     size_t first, size_t end, replay_report_t *r, magcal_ellipsoid_cal_t *cal);

#endif
