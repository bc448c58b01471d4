/* magcal-replay: the part that drives the library (replay port + calibrator), kept apart from
 * the CLI so the code path is exactly the firmware's: port read -> poll -> run -> classify. */
#ifndef MAGCAL_REPLAY_CAL_H
#define MAGCAL_REPLAY_CAL_H

#include <stddef.h>

#include "magcal/calibrator.h"
#include "replay_csv.h"
#include "replay_report.h"

typedef struct {
    const char *filter;          /* optics | optics-classic | dbscan | none */
    double eps;                  /* NaN = automatic */
    long min_pts;                /* 0 = automatic */
    magcal_replay_plane_t plane; /* dump axes -> library axes */
    int plain;                   /* --no-consensus: filter none + cfg.use_consensus = 0 */
} replay_options_t;

typedef struct {
    magcal_cal2d_t cal;      /* adopted calibration (valid when the run succeeded) */
    unsigned char *flags;    /* n_fed entries, allocated by the caller: 1 = outlier */
    int have_fit;            /* classify() usable */
} replay_result_t;

/** Machine-readable status name (lower-case enum name without MAGCAL_ERR_; "ok"). */
const char *replay_status_id(magcal_status_t st);

/** Most samples one calibration run holds (the calibrator's capacity). */
size_t replay_capacity(void);

/**
 * Serve rows first, first+step, ... (n_fed rows) of the dump through the replay port, poll them
 * into a calibrator configured from `o` (accept-all), run it, and fill r's outcome and geometry
 * and res. Returns REPLAY_EXIT_OK, REPLAY_EXIT_CAL_FAILED (r->status/reason say why),
 * REPLAY_EXIT_USAGE (options the library rejects) or REPLAY_EXIT_INTERNAL.
 */
int replay_calibrate(const replay_options_t *o, const magcal_replay_csv_t *d, size_t first,
                     size_t n_fed, size_t step, replay_report_t *r, replay_result_t *res);

/** Estimated heading error (deg) of the run's calibration from the library's report (NaN when
 *  the run stopped before the estimate). The one place that reads it. */
double replay_est_heading_err_deg(const magcal_cal_report_t *rep, magcal_status_t st);

/** The adoption rule that adopted the run's calibration, or what refused it (text). */
const char *replay_adopt_rule(const magcal_cal_report_t *rep, magcal_status_t st);

/** 1 when the last run's final fit judges raw as an outlier (0 when there is no fit). */
int replay_classify(const replay_result_t *res, magcal_vec2_t raw);

#endif
