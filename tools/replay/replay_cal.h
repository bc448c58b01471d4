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
} replay_options_t;

typedef struct {
    magcal_cal2d_t cal;      /* adopted calibration (valid when the run succeeded) */
    unsigned char *flags;    /* n_fed entries, allocated by the caller: 1 = outlier */
    int have_fit;            /* classify() usable */
} replay_result_t;

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

/** 1 when the last run's final fit judges raw as an outlier (0 when there is no fit). */
int replay_classify(const replay_result_t *res, magcal_vec2_t raw);

#endif
