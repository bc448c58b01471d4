/**
 * @file replay_csv.h
 * @brief Host-only reader of magnetometer dump CSV files, and the loader that turns the rows into
 *        the arrays magcal_port_replay_start() serves.
 *
 * Format (docs/replay.md has the full description):
 * - the first line that is neither blank nor a comment is the header, naming the columns;
 * - recognised columns (case-insensitive, any order): `t` (s), `mx,my,mz` (field, any unit),
 *   `ax,ay,az` (accelerometer), `heading_ref_deg`, `cog_deg`, `speed_mps`, `glitch`, `outlier`,
 *   and for the aided mode `roll_deg, pitch_deg, yaw_deg, lat_deg, lon_deg, height_km,
 *   decimal_year, dop`;
 *   every other column is ignored (its cells are not even looked at);
 * - fields are separated by `,`; a header without a comma that has `;` (or else a tab) makes that
 *   the separator of the whole file (magcal_replay_csv_t::sep);
 * - a missing required column's message lists the header's names, suggests the likely renames of
 *   unrecognised ones (`mag_x`, `x`, `mx (uT)` -> mx) and lists the accepted names; on success the
 *   unrecognised columns are described in magcal_replay_csv_t::note;
 * - lines whose first non-blank character is `#`, and blank lines, are skipped anywhere;
 * - LF or CRLF line ends, an optional UTF-8 byte order mark, spaces/tabs around cells, and cells
 *   wrapped in double quotes (without commas inside) are accepted;
 * - a cell of a recognised column is a decimal number (`-1.5`, `2e-3`), or empty / `nan`
 *   (case-insensitive) meaning "missing", which is allowed only in columns the caller did not mark
 *   required. `inf`, hex, `1.2.3`, trailing text, a magnitude above FLT_MAX (it would not
 *   convert to the library's float32), ... are errors.
 *
 * Errors are never silent: a malformed file fails as a whole with a message
 * `FILE:LINE:COL: what` (COL = 1-based field number; `FILE:LINE: what` when no single field is at
 * fault), and no row is ever skipped while being counted as data.
 *
 * Limits (checked, each gives an error, never undefined behaviour): file size
 * MAGCAL_REPLAY_CSV_MAX_BYTES, rows MAGCAL_REPLAY_CSV_MAX_ROWS, fields per line
 * MAGCAL_REPLAY_CSV_MAX_FIELDS, characters of a numeric cell MAGCAL_REPLAY_CSV_MAX_NUMBER_LEN.
 * Line length is limited only by the file size. The reader allocates with malloc (host tool);
 * magcal_replay_csv_free() releases everything.
 */
#ifndef MAGCAL_REPLAY_CSV_H
#define MAGCAL_REPLAY_CSV_H

#include <stddef.h>
#include <stdint.h>

#include "magcal/status.h"
#include "magcal/types.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Largest dump file accepted, in bytes (256 MiB). */
#define MAGCAL_REPLAY_CSV_MAX_BYTES (256u * 1024u * 1024u)
/** Largest number of data rows accepted. */
#define MAGCAL_REPLAY_CSV_MAX_ROWS 4000000u
/** Largest number of comma-separated fields in one line (header or data). */
#define MAGCAL_REPLAY_CSV_MAX_FIELDS 4096u
/** Longest numeric cell, in characters after trimming. */
#define MAGCAL_REPLAY_CSV_MAX_NUMBER_LEN 63u
/** A message buffer of this size always holds a whole error message. */
#define MAGCAL_REPLAY_CSV_ERR_LEN 2048u
/** Size of the header note (magcal_replay_csv_t::note). */
#define MAGCAL_REPLAY_CSV_NOTE_LEN 1024u

/** Recognised columns. */
typedef enum {
    MAGCAL_REPLAY_COL_T = 0,       /**< time, seconds (start-relative or absolute) */
    MAGCAL_REPLAY_COL_MX,          /**< magnetometer x, dump unit */
    MAGCAL_REPLAY_COL_MY,          /**< magnetometer y */
    MAGCAL_REPLAY_COL_MZ,          /**< magnetometer z */
    MAGCAL_REPLAY_COL_AX,          /**< accelerometer x */
    MAGCAL_REPLAY_COL_AY,          /**< accelerometer y */
    MAGCAL_REPLAY_COL_AZ,          /**< accelerometer z */
    MAGCAL_REPLAY_COL_HEADING_REF, /**< reference heading, degrees clockwise from north */
    MAGCAL_REPLAY_COL_COG,         /**< GNSS course over ground, degrees */
    MAGCAL_REPLAY_COL_SPEED,       /**< GNSS speed, m/s */
    MAGCAL_REPLAY_COL_GLITCH,      /**< importer's glitch flag on recorded dumps (1 = bad sample) */
    MAGCAL_REPLAY_COL_OUTLIER,     /**< truth flag on synthetic dumps (1 = injected outlier) */
    MAGCAL_REPLAY_COL_ROLL,        /**< INS roll, degrees (aided.h convention: right side down +) */
    MAGCAL_REPLAY_COL_PITCH,       /**< INS pitch, degrees (nose up +) */
    MAGCAL_REPLAY_COL_YAW,         /**< INS yaw, degrees clockwise from true north */
    MAGCAL_REPLAY_COL_LAT,         /**< WGS 84 geodetic latitude, degrees north + */
    MAGCAL_REPLAY_COL_LON,         /**< longitude, degrees east + */
    MAGCAL_REPLAY_COL_HEIGHT,      /**< height above the WGS 84 ellipsoid, km */
    MAGCAL_REPLAY_COL_YEAR,        /**< decimal year (e.g. 2026.5) */
    MAGCAL_REPLAY_COL_DOP,         /**< GNSS dilution of precision */
    MAGCAL_REPLAY_COL_GX,          /**< gyro x (rate about body x; --gyro-unit) */
    MAGCAL_REPLAY_COL_GY,          /**< gyro y */
    MAGCAL_REPLAY_COL_GZ,          /**< gyro z */
    MAGCAL_REPLAY_COL_COUNT
} magcal_replay_col_t;

/** Bit of column c in a `required` mask. */
#define MAGCAL_REPLAY_COL_BIT(c) (1u << (unsigned)(c))

/** A loaded dump. Every pointer is owned by the object (free with magcal_replay_csv_free()). */
typedef struct {
    size_t n_rows;                           /**< data rows */
    double *col[MAGCAL_REPLAY_COL_COUNT];    /**< n_rows values each (NaN = missing cell);
                                                  NULL when the header lacks the column */
    size_t *line;                            /**< 1-based source line of each data row */
    char sep;                                /**< field separator found: ',', ';' or '\t' */
    char note[MAGCAL_REPLAY_CSV_NOTE_LEN];   /**< "" or the header's columns that are not read,
                                                  quoted, with suggested names ("\"mag_x\" -> mx")
                                                  and the accepted names: for a warning */
} magcal_replay_csv_t;

/**
 * @brief Axis mapping from the dump's (mx, my, mz) to the library frame. `src[k]` is the dump
 *        axis (0 = x, 1 = y, 2 = z) that becomes library axis k; the library's horizontal plane
 *        is (x, y). Built by magcal_replay_csv_plane().
 */
typedef struct {
    unsigned src[3];
} magcal_replay_plane_t;

/** @brief Column name as written in headers ("mx", "heading_ref_deg", ...); "?" when unknown. */
const char *magcal_replay_csv_col_name(magcal_replay_col_t c);

/**
 * @brief Parse a dump held in memory.
 * @param[in]  text     the bytes (need not be NUL-terminated; NUL bytes in it are an error).
 * @param[in]  len      number of bytes.
 * @param[in]  name     file name used in messages (NULL gives "<input>").
 * @param[in]  required mask of MAGCAL_REPLAY_COL_BIT(): columns that must be in the header and
 *                      must have a number in every row.
 * @param[out] out      the dump; on failure it is left empty (nothing to free).
 * @param[out] err      message buffer (may be NULL); filled on failure, "" on success.
 * @param[in]  err_len  size of err (MAGCAL_REPLAY_CSV_ERR_LEN always suffices).
 * @return MAGCAL_OK; MAGCAL_ERR_NULL (text or out NULL); MAGCAL_ERR_ARG (malformed content:
 *         bad number, wrong field count, missing/duplicate column, NUL byte);
 *         MAGCAL_ERR_NO_DATA (no header or no data row); MAGCAL_ERR_BUFFER_FULL (a limit above
 *         exceeded, or out of memory).
 */
magcal_status_t magcal_replay_csv_parse(const char *text, size_t len, const char *name,
                                        uint32_t required, magcal_replay_csv_t *out, char *err,
                                        size_t err_len);

/**
 * @brief Read and parse a dump file ("-" reads standard input).
 * @return as magcal_replay_csv_parse(), plus MAGCAL_ERR_PORT when the file cannot be opened or
 *         read (the message names the file and the system's reason).
 */
magcal_status_t magcal_replay_csv_read(const char *path, uint32_t required,
                                       magcal_replay_csv_t *out, char *err, size_t err_len);

/** @brief Release a dump (safe on a zeroed or already freed object, and on NULL). */
void magcal_replay_csv_free(magcal_replay_csv_t *d);

/**
 * @brief Parse a plane name: XY, XZ, YZ (or the swapped YX, ZX, ZY, which mirror the heading
 *        sense), case-insensitive. The first letter becomes library x, the second library y, the
 *        remaining axis library z. No sign is changed.
 * @return MAGCAL_OK; MAGCAL_ERR_NULL; MAGCAL_ERR_ARG for any other string (out untouched).
 */
magcal_status_t magcal_replay_csv_plane(const char *s, magcal_replay_plane_t *out);

/**
 * @brief Fill the arrays magcal_port_replay_start() serves from rows first, first+step, ...
 *        (count rows), mapped through `plane` and converted to float.
 * @param[in]  d      the dump.
 * @param[in]  first  first row.
 * @param[in]  count  number of output rows; first + (count-1)*step must be < d->n_rows.
 * @param[in]  step   row stride (>= 1; a decimation factor).
 * @param[in]  plane  axis mapping (NULL = XY).
 * @param[out] mag    count field vectors (required). The two in-plane components must be finite;
 *                    a missing out-of-plane component (a 2-axis dump) is written as 0.
 * @param[out] accel  count accelerometer vectors, or NULL. When given, ax, ay, az must all be
 *                    present and finite in the rows used.
 * @param[out] t_ms   count timestamps in ms relative to row `first`, or NULL. When given, t must
 *                    be present, finite and non-decreasing, spanning less than 2^32 ms.
 * @return MAGCAL_OK; MAGCAL_ERR_NULL (d or mag NULL); MAGCAL_ERR_ARG (range, step 0, decreasing
 *         time); MAGCAL_ERR_NO_DATA (a needed column is absent); MAGCAL_ERR_NONFINITE (a needed
 *         cell is missing). On failure the outputs may be partly written.
 */
magcal_status_t magcal_replay_csv_fill(const magcal_replay_csv_t *d, size_t first, size_t count,
                                       size_t step, const magcal_replay_plane_t *plane,
                                       magcal_vec3_t *mag, magcal_vec3_t *accel, uint32_t *t_ms);

#ifdef __cplusplus
}
#endif

#endif /* MAGCAL_REPLAY_CSV_H */
