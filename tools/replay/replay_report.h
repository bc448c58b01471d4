/* magcal-replay: the report the harness fills and prints (table or JSON, docs/replay.md). */
#ifndef MAGCAL_REPLAY_REPORT_H
#define MAGCAL_REPLAY_REPORT_H

#include <stddef.h>

/** Exit codes of magcal-replay (docs/replay.md). */
enum {
    REPLAY_EXIT_OK = 0,          /* calibration succeeded, report written */
    REPLAY_EXIT_USAGE = 1,       /* bad command line */
    REPLAY_EXIT_INPUT = 2,       /* dump unreadable or malformed, or options do not fit it */
    REPLAY_EXIT_CAL_FAILED = 3,  /* the library refused the calibration (status + reason) */
    REPLAY_EXIT_OUTPUT = 4,      /* an output file could not be written */
    REPLAY_EXIT_INTERNAL = 5     /* unexpected library status (a bug: please report) */
};

/** Most distinct reference headings reported one by one (more: 45-degree sectors). */
#define REPLAY_MAX_REF_GROUPS 72u

typedef struct {
    double ref_deg;   /* reference heading (exact value, or sector centre) */
    size_t n;
    double rms_deg;
    double bias_deg;
    double max_abs_deg;
} replay_ref_group_t;

typedef struct {
    /* run description */
    const char *file;
    const char *filter;
    const char *plane;
    double declination_deg;
    double eps;       /* NaN = automatic */
    long min_pts;     /* 0 = automatic */
    size_t cal_first, cal_end;
    /* outcome */
    const char *status;  /* "ok" or the library's status name */
    int status_code;     /* magcal_status_t value */
    char reason[256];
    /* counts */
    size_t n_rows, n_cal, n_fed, decimation, n_used, n_outliers;
    size_t capacity;
    /* geometry (dump units) */
    double coverage_deg;
    double center[2];
    double correction[2][2];
    double ell_center[2];
    double semi_axes[2]; /* major, minor */
    double angle_deg;    /* direction of the major axis, ccw from +x, (-90, 90] */
    double radius;
    double residual_rms;
    double spread_raw;       /* std/mean of |raw| (from the origin) over the samples used */
    double spread_raw_all;   /* the same over every fed calibration sample, outliers included */
    double spread_corrected; /* std/mean of |M (raw - centre)| over the samples used */
    int have_geometry;
    /* truth flags from the dump (glitch / outlier column) over the fed rows */
    const char *truth_column; /* NULL when the dump has none */
    size_t truth_flagged, truth_detected, truth_missed, false_alarms;
    /* heading against reference (non-calibration rows) */
    size_t n_heading;           /* rows with a reference used in the metrics */
    size_t n_heading_flagged;   /* of those, rows the final fit classifies as outliers (still used) */
    double heading_rms_deg, heading_bias_deg, heading_max_abs_deg;
    int by_ref_sectors; /* 1 when grouped in 45-degree sectors */
    size_t n_groups;
    replay_ref_group_t groups[REPLAY_MAX_REF_GROUPS];
} replay_report_t;

/** Print the report as a readable table. */
void replay_print_table(const replay_report_t *r);

/** Print the report as one JSON object (one line + newline). Returns 0, or -1 on failure. */
int replay_print_json(const replay_report_t *r);

#endif
