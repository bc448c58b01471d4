/* magcal-replay: plausibility checks of a dump and of the run's result. Each finds one of the
 * mistakes users make (units, frames, signs, options) from the data alone and adds a warning
 * with the fix to the report (docs/replay.md, "Warnings"). None changes a result, except
 * replay_check_vehicle(), whose verdict the CLI uses to turn the 2d tilt compensation off. */
#ifndef MAGCAL_REPLAY_CHECKS_H
#define MAGCAL_REPLAY_CHECKS_H

#include <stddef.h>

#include "magcal/types.h"
#include "replay_csv.h"
#include "replay_report.h"

/** Header: the columns that are not read (with suggested names) and a non-comma separator. */
void replay_check_columns(const magcal_replay_csv_t *d, replay_warnings_t *w);

/** heading_ref_deg all within [-2 pi, 2 pi] while spanning more than 1: radians? */
void replay_check_ref_units(const magcal_replay_csv_t *d, replay_warnings_t *w);

/** Aided: the INS yaw within +/- 2 pi while spanning more than 1: radians? */
void replay_check_ins_angles(const magcal_replay_csv_t *d, replay_warnings_t *w);

/**
 * Accelerometer (mapped by plane; every test is a ratio, so any unit) like a turning vehicle's: rows
 * with a horizontal acceleration above 0.15 g whose norm rises with it as on a level road
 * (|a| ~ sqrt(1 + h^2): centripetal acceleration added to gravity) instead of staying at 1 g (a
 * static tilt). Returns 1 when at least 5 % of the rows are such and the median norm excess is at
 * least half the centripetal model's; *share gets the share of such rows. No warning is added.
 */
int replay_check_vehicle(const magcal_replay_csv_t *d, const magcal_replay_plane_t *plane, double *share,
                         double *excess_ratio);

/** The accelerometer's z (library frame, relative to |a|) reads about -1 g: z points down (NED frame, or
 *  mounted upside down). */
void replay_check_accel_down(const magcal_replay_csv_t *d, const magcal_replay_plane_t *plane,
                             replay_warnings_t *w);

/** --eps far (below 1e-3 x or above 1 x) from the data's scale: the median distance of the
 *  calibration samples (m[0..n), x, y in 2d, all three axes in 3d) from their mean. */
void replay_check_eps(const magcal_vec3_t *m, size_t n, int three_d, double eps, const char *unit,
                      replay_warnings_t *w);

/** Aided: median |m| of the calibration rows against the median |B_ref| (dump unit) of the same
 *  rows; outside [1/3, 3] suggests the unit that fits. unit_per_nt: the unit in use. */
void replay_check_field_wmm(const magcal_vec3_t *m, const double *b_ned3, size_t first, size_t end,
                            double unit_per_nt, const char *unit, const char *model, replay_warnings_t *w);

/** 2d: a dump that is not level (the out-of-plane field axis varies, the accelerometer tilts, or
 *  the corrected radius still varies as for a 3-D motion projected on the plane): try --mode 3d.
 *  fed: every row mapped into the library frame (z = the third axis, 0 when absent). */
void replay_check_level(const magcal_replay_csv_t *d, const magcal_vec3_t *fed, const magcal_replay_plane_t *plane,
                        int vehicle, const replay_report_t *r, replay_warnings_t *w);

/** After the heading metrics (success, >= 10 verification rows with a reference): an RMS above
 *  10 deg with a good spread reduction whose errors are a mirror (heading + reference constant:
 *  axes swapped or NED frame, try --plane YX) or a constant bias (rotated mounting or a flipped
 *  sign). hdg_deg / ref_deg: n_rows entries (NaN = none). */
void replay_check_heading_pattern(const double *hdg_deg, const double *ref_deg, size_t n_rows,
                                  const replay_report_t *r, double spread_ratio, replay_warnings_t *w);

/** 2d / 3d with --field-unit: the calibrated radius (horizontal) or field magnitude outside what
 *  the Earth's field gives in that unit (0.5..100 uT horizontal, 10..100 uT total). */
void replay_check_field_range(double magnitude, int horizontal, const char *unit, replay_warnings_t *w);

#endif
