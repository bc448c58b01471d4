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

/** Tilt gate outcomes counted per row (index order of the JSON `tilt.gates` object). */
enum {
    REPLAY_TILT_OK = 0,
    REPLAY_TILT_FREE_FALL,
    REPLAY_TILT_ACCEL_NORM,
    REPLAY_TILT_GIMBAL,
    REPLAY_TILT_ZERO_FIELD,
    REPLAY_TILT_NO_ACCEL, /* accelerometer cell missing (nan) or another non-finite input */
    REPLAY_TILT_COUNT
};

/** Most warnings one report carries. */
#define REPLAY_MAX_WARNINGS 16u

typedef struct {
    const char *id;  /* stable key, e.g. "ref_radians" (docs/replay.md "Warnings") */
    char text[480];  /* what looks wrong, the numbers, and the fix */
} replay_warning_t;

/** Warnings of a report (kept apart from replay_report_t so it can be cleared in one go). */
typedef struct {
    size_t n;
    replay_warning_t w[REPLAY_MAX_WARNINGS];
} replay_warnings_t;

/** Most coefficients a reported swing / Fourier model has. */
#define REPLAY_MAX_SWING_COEF 12u

typedef struct {
    /* run description */
    const char *mode; /* "2d" | "3d" | "aided" */
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
    size_t n_outlier_rows; /* 3d / aided: rows with outlier = 1 in the headings CSV (all rows) */
    size_t capacity;
    /* geometry (dump units) */
    double coverage_deg;
    double missing_start_deg, missing_width_deg; /* 2d: largest uncovered sector (width 0: none) */
    double est_heading_err_deg;  /* 2d: the library's estimate of the heading error; NaN = none */
    const char *adopt_rule;      /* 2d: the rule that adopted, or what refused */
    const char *fit;             /* 2d: "consensus" (default) | "plain" (--no-consensus) */
    double filter_eps_used;      /* 2d: eps' the density filter used (0: no filter) */
    const char *unit;            /* field unit of the report: "uT" | "nT" | "gauss" | NULL = dump units */
    char sep;                    /* the dump's field separator */
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
    /* rows excluded from the heading metrics besides the calibration rows (the swing's
     * reference rows); ref_first == ref_end = none */
    size_t ref_first, ref_end;

    /* ---- compass swing (--ref-rows) */
    int swing_requested;
    const char *swing_status;     /* "ok" or the status name */
    int swing_status_code;
    const char *swing_model;      /* "smith" | "fourier" */
    const char *swing_method;     /* "bins" (one point per 10-degree bin) | "pairs" (every row) */
    size_t swing_n_ref;           /* reference rows with a finite heading and reference */
    size_t swing_n_points;        /* points of the final fit (bins or rows) */
    size_t swing_ncoef;           /* coefficients in swing_coef (0 when not fitted) */
    double swing_coef[REPLAY_MAX_SWING_COEF];
    unsigned swing_order;         /* Fourier order K */
    double swing_fit_rms_deg, swing_fit_max_deg;
    /* heading metrics before the swing (same rows) */
    size_t n_heading_before;
    double rms_before, bias_before, max_before;

    /* ---- tilt compensation */
    int tilt_on;
    const char *accel_unit;        /* "g" | "mps2" */
    const char *accel_unit_source; /* "detected" | "given" */
    double accel_median_norm;      /* in the dump's unit */
    const char *tilt_field;        /* how the 3-axis field was formed (text) */
    double tilt_z_offset;          /* 2d mode: mean mz over the calibration rows */
    double tilt_hz_level;          /* 2d mode: level vertical component used (calibrated units) */
    double inclination_deg;        /* NaN = not given */
    size_t tilt_counts[REPLAY_TILT_COUNT];

    /* ---- 3-D ellipsoid calibration */
    int have_3d;
    double off3[3];
    double mat3[3][3];
    double field3;
    const char *model3;
    double coverage3;
    size_t n_rejected3;           /* 3d: rejected by the fit's residual gate */
    size_t n_density3;            /* 3d: rejected by the OPTICS density stage (0 with --filter none) */
    double eps3, eps_prime3;      /* 3d: density-stage parameters used (NaN when skipped) */
    long min_pts3;                /* 3d: density-stage MinPts used (0 when skipped) */

    /* ---- aided */
    int have_aided;               /* a result (G, V) exists */
    const char *aided_status;
    int aided_status_code;
    const char *field_unit;       /* unit of the dump's field: "uT" | "nT" | "gauss" */
    const char *prior;            /* "identity" or the --prior file name */
    double prior_g_scale;         /* factor applied to a 3d report's G (|B_ref| / its F), else 1 */
    double b_ref_first[3];        /* B_ref (NED, dump unit) of the first epoch fed */
    double decl_first_deg;        /* WMM declination of the first epoch fed */
    size_t aided_seen, aided_accepted, aided_gated[5];
    size_t aided_skipped;         /* rows not fed: a needed cell missing */
    long converged_at, converged_row; /* -1 = not converged */
    unsigned aided_flags, n_prior_dirs;
    double min_eig, weak_std, resid_rms_aided;
    const char *aided_objective;  /* input: "combined" (default) | "vector" (--aided-objective) */
    const char *geomag_model;     /* aided: "WMM2025" | "IGRF-14" (--model) */
    double resid_f_rms_aided;     /* a-priori total-field residual RMS of the last window */
    size_t n_total_field;         /* accepted epochs whose total-field residual entered the objective */

    /* ---- plausibility warnings (replay_checks.c) */
    replay_warnings_t warnings;
} replay_report_t;

/** Add a warning (printf format) and print it on stderr ("magcal-replay: warning: ..."). */
void replay_warn(replay_warnings_t *ws, const char *id, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 3, 4)))
#endif
    ;

/** Print the report as a readable table. */
void replay_print_table(const replay_report_t *r);

/** Print the report as one JSON object (one line + newline). Returns 0, or -1 on failure. */
int replay_print_json(const replay_report_t *r);

#endif
