/* Tests of the host CSV dump reader (port/replay/replay_csv.c): format features, exact error
 * messages, limits, hostile input (long lines, truncation, binary), and the port loader. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "magcal_port_replay.h"
#include "replay_csv.h"
#include "unity.h"

#define REQ_XY (MAGCAL_REPLAY_COL_BIT(MAGCAL_REPLAY_COL_MX) | MAGCAL_REPLAY_COL_BIT(MAGCAL_REPLAY_COL_MY))

/* Unity 2.4.3 has no size_t assertion; compare as 64-bit unsigned. */
#define ASSERT_SIZE(e, a) TEST_ASSERT_EQUAL_UINT64((UNITY_UINT64)(e), (UNITY_UINT64)(a))

static magcal_replay_csv_t g_d;
static char g_err[MAGCAL_REPLAY_CSV_ERR_LEN];

void setUp(void)
{
    memset(&g_d, 0, sizeof g_d);
    g_err[0] = '\0';
}
void tearDown(void) { magcal_replay_csv_free(&g_d); }

static magcal_status_t parse(const char *text, uint32_t req)
{
    return magcal_replay_csv_parse(text, strlen(text), "dump.csv", req, &g_d, g_err, sizeof g_err);
}

static void test_parse_any_column_order_extra_columns_comments_crlf_reads_values(void)
{
    const char *text = "# recorded 2026-01-01\r\n"
                       "\r\n"
                       "foo, my ,MX,heading_ref_deg,t\r\n"
                       "abc,2.5,-1e-3,,0.0\r\n"
                       "  # a comment between rows\r\n"
                       "x y,\"3\",4,NaN,0.1\r\n"
                       "\r\n"
                       ",-0,+7.25E+1,90,0.2"; /* last line without newline */
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, parse(text, REQ_XY));
    TEST_ASSERT_EQUAL_STRING("", g_err);
    ASSERT_SIZE(3u, g_d.n_rows);
    TEST_ASSERT_NULL(g_d.col[MAGCAL_REPLAY_COL_MZ]);
    TEST_ASSERT_NULL(g_d.col[MAGCAL_REPLAY_COL_AX]);
    TEST_ASSERT_EQUAL_DOUBLE(-1e-3, g_d.col[MAGCAL_REPLAY_COL_MX][0]);
    TEST_ASSERT_EQUAL_DOUBLE(2.5, g_d.col[MAGCAL_REPLAY_COL_MY][0]);
    TEST_ASSERT_EQUAL_DOUBLE(3.0, g_d.col[MAGCAL_REPLAY_COL_MY][1]);
    TEST_ASSERT_EQUAL_DOUBLE(72.5, g_d.col[MAGCAL_REPLAY_COL_MX][2]);
    TEST_ASSERT_TRUE(isnan(g_d.col[MAGCAL_REPLAY_COL_HEADING_REF][0]));
    TEST_ASSERT_TRUE(isnan(g_d.col[MAGCAL_REPLAY_COL_HEADING_REF][1]));
    TEST_ASSERT_EQUAL_DOUBLE(90.0, g_d.col[MAGCAL_REPLAY_COL_HEADING_REF][2]);
    TEST_ASSERT_EQUAL_DOUBLE(0.2, g_d.col[MAGCAL_REPLAY_COL_T][2]);
    ASSERT_SIZE(4u, g_d.line[0]);
    ASSERT_SIZE(6u, g_d.line[1]);
    ASSERT_SIZE(8u, g_d.line[2]);
}

static void test_parse_aided_columns_are_recognised_and_required_ones_checked(void)
{
    const uint32_t req = REQ_XY | MAGCAL_REPLAY_COL_BIT(MAGCAL_REPLAY_COL_ROLL) |
                         MAGCAL_REPLAY_COL_BIT(MAGCAL_REPLAY_COL_HEIGHT);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK,
                          parse("mx,my,roll_deg,pitch_deg,yaw_deg,lat_deg,lon_deg,height_km,decimal_year,dop\n"
                                "1,2,-1.5,2.5,359.5,48.1,11.6,0.52,2026.5,\n",
                                req));
    TEST_ASSERT_EQUAL_DOUBLE(-1.5, g_d.col[MAGCAL_REPLAY_COL_ROLL][0]);
    TEST_ASSERT_EQUAL_DOUBLE(2.5, g_d.col[MAGCAL_REPLAY_COL_PITCH][0]);
    TEST_ASSERT_EQUAL_DOUBLE(359.5, g_d.col[MAGCAL_REPLAY_COL_YAW][0]);
    TEST_ASSERT_EQUAL_DOUBLE(48.1, g_d.col[MAGCAL_REPLAY_COL_LAT][0]);
    TEST_ASSERT_EQUAL_DOUBLE(11.6, g_d.col[MAGCAL_REPLAY_COL_LON][0]);
    TEST_ASSERT_EQUAL_DOUBLE(0.52, g_d.col[MAGCAL_REPLAY_COL_HEIGHT][0]);
    TEST_ASSERT_EQUAL_DOUBLE(2026.5, g_d.col[MAGCAL_REPLAY_COL_YEAR][0]);
    TEST_ASSERT_TRUE(isnan(g_d.col[MAGCAL_REPLAY_COL_DOP][0])); /* optional: empty = missing */
    TEST_ASSERT_EQUAL_STRING("dop", magcal_replay_csv_col_name(MAGCAL_REPLAY_COL_DOP));
    magcal_replay_csv_free(&g_d);
    /* the gyro's rates (the stream's gyro heading check), names case-insensitive */
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, parse("mx,my,gx,GY,gz\n1,2,0.5,-0.25,0.125\n", REQ_XY));
    TEST_ASSERT_EQUAL_DOUBLE(0.5, g_d.col[MAGCAL_REPLAY_COL_GX][0]);
    TEST_ASSERT_EQUAL_DOUBLE(-0.25, g_d.col[MAGCAL_REPLAY_COL_GY][0]);
    TEST_ASSERT_EQUAL_DOUBLE(0.125, g_d.col[MAGCAL_REPLAY_COL_GZ][0]);
    TEST_ASSERT_EQUAL_STRING("gz", magcal_replay_csv_col_name(MAGCAL_REPLAY_COL_GZ));
    magcal_replay_csv_free(&g_d);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, parse("mx,my,roll_deg,height_km\n1,2,nan,0.5\n", req));
    TEST_ASSERT_EQUAL_STRING("dump.csv:2:3: column \"roll_deg\" is required, got \"nan\"", g_err);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, parse("mx,my,roll_deg\n1,2,3\n", req));
    TEST_ASSERT_EQUAL_STRING("dump.csv:1: missing required column \"height_km\" in the header (read as "
                             "comma-separated; found: mx, my, roll_deg; accepted names: t, mx, my, mz, ax, ay, "
                             "az, heading_ref_deg, cog_deg, speed_mps, glitch, outlier, roll_deg, pitch_deg, "
                             "yaw_deg, lat_deg, lon_deg, height_km, decimal_year, dop, gx, gy, gz)",
                             g_err);
}

static void test_parse_bad_number_names_file_line_and_field(void)
{
    const char *text = "t,mx,my\n0,1,2\n0.1,1,2\n0.2,3,1.2.3\n";
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, parse(text, REQ_XY));
    TEST_ASSERT_EQUAL_STRING("dump.csv:4:3: expected a number, got \"1.2.3\" (column my)", g_err);
    ASSERT_SIZE(0u, g_d.n_rows);
    TEST_ASSERT_NULL(g_d.col[MAGCAL_REPLAY_COL_MX]);
}

static void test_parse_rejects_inf_hex_and_trailing_text(void)
{
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, parse("mx,my\n1,inf\n", REQ_XY));
    TEST_ASSERT_EQUAL_STRING("dump.csv:2:2: expected a number, got \"inf\" (column my)", g_err);
    magcal_replay_csv_free(&g_d);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, parse("mx,my\n0x10,1\n", REQ_XY));
    TEST_ASSERT_EQUAL_STRING("dump.csv:2:1: expected a number, got \"0x10\" (column mx)", g_err);
    magcal_replay_csv_free(&g_d);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, parse("mx,my\n1,2 uT\n", REQ_XY));
    TEST_ASSERT_EQUAL_STRING("dump.csv:2:2: expected a number, got \"2 uT\" (column my)", g_err);
    magcal_replay_csv_free(&g_d);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, parse("mx,my\n1,1e999\n", REQ_XY));
    TEST_ASSERT_EQUAL_STRING("dump.csv:2:2: number out of range, got \"1e999\" (column my)", g_err);
}

static void test_parse_garbage_in_unrecognised_column_is_ignored(void)
{
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, parse("note,mx,my\nhello \"world\",1,2\n", REQ_XY));
    ASSERT_SIZE(1u, g_d.n_rows);
}

static void test_parse_garbage_in_optional_recognised_column_is_an_error(void)
{
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, parse("mx,my,heading_ref_deg\n1,2,north\n", REQ_XY));
    TEST_ASSERT_EQUAL_STRING("dump.csv:2:3: expected a number, got \"north\" (column heading_ref_deg)",
                             g_err);
}

static void test_parse_missing_cell_in_required_column_is_an_error(void)
{
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, parse("mx,my,mz\n1,2,nan\n1,,3\n", REQ_XY));
    TEST_ASSERT_EQUAL_STRING("dump.csv:3:2: column \"my\" is required, got an empty cell", g_err);
    magcal_replay_csv_free(&g_d);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, parse("mx,my\nnan,1\n", REQ_XY));
    TEST_ASSERT_EQUAL_STRING("dump.csv:2:1: column \"mx\" is required, got \"nan\"", g_err);
}

static void test_parse_missing_required_column_names_it(void)
{
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, parse("# c\nt,mx,mz\n0,1,2\n", REQ_XY));
    TEST_ASSERT_EQUAL_STRING("dump.csv:2: missing required column \"my\" in the header (read as "
                             "comma-separated; found: t, mx, mz; accepted names: t, mx, my, mz, ax, ay, az, "
                             "heading_ref_deg, cog_deg, speed_mps, glitch, outlier, roll_deg, pitch_deg, "
                             "yaw_deg, lat_deg, lon_deg, height_km, decimal_year, dop, gx, gy, gz)",
                             g_err);
    TEST_ASSERT_EQUAL_STRING("", g_d.note);
}

/* The usual header mistakes: the message lists what it found and suggests the rename. */
static void test_parse_missing_column_suggests_aliases(void)
{
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, parse("mag_x,mag_y,mag_z\n1,2,3\n", REQ_XY));
    TEST_ASSERT_NOT_NULL(strstr(g_err, "found: \"mag_x\", \"mag_y\", \"mag_z\"; did you mean \"mag_x\" -> mx, "
                                       "\"mag_y\" -> my, \"mag_z\" -> mz?"));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, parse("x,y,z\n1,2,3\n", REQ_XY));
    TEST_ASSERT_NOT_NULL(strstr(g_err, "did you mean \"x\" -> mx, \"y\" -> my, \"z\" -> mz?"));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, parse("mx (uT),my (uT)\n1,2\n", REQ_XY));
    TEST_ASSERT_NOT_NULL(strstr(g_err, "\"mx (uT)\" -> mx (unit ut), \"my (uT)\" -> my (unit ut)"));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, parse("t mx my\n0 1 2\n", REQ_XY));
    TEST_ASSERT_NOT_NULL(strstr(g_err, "space-separated?"));
    /* a recognised column is never "suggested" again */
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, parse("mx,x,y\n1,2,3\n", REQ_XY));
    TEST_ASSERT_NOT_NULL(strstr(g_err, "did you mean \"y\" -> my?"));
}

static void test_parse_semicolon_and_tab_separators_are_detected(void)
{
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, parse("t;mx;my\n0;1.5;-2\n0.1;3;4\n", REQ_XY));
    TEST_ASSERT_EQUAL_INT(';', g_d.sep);
    ASSERT_SIZE(2u, g_d.n_rows);
    TEST_ASSERT_EQUAL_DOUBLE(-2.0, g_d.col[MAGCAL_REPLAY_COL_MY][0]);
    magcal_replay_csv_free(&g_d);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, parse("t\tmx\tmy\n0\t1.5\t-2\n", REQ_XY));
    TEST_ASSERT_EQUAL_INT('\t', g_d.sep);
    TEST_ASSERT_EQUAL_DOUBLE(1.5, g_d.col[MAGCAL_REPLAY_COL_MX][0]);
    magcal_replay_csv_free(&g_d);
    /* a decimal comma in a ';' file is a number error, not a silent split */
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, parse("mx;my\n1,5;2\n", REQ_XY));
    TEST_ASSERT_EQUAL_STRING("dump.csv:2:1: expected a number, got \"1,5\" (column mx)", g_err);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, parse("mx,my\n1,2\n", REQ_XY));
    TEST_ASSERT_EQUAL_INT(',', g_d.sep);
}

static void test_parse_unknown_columns_are_described_in_the_note(void)
{
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, parse("mx,my,heading_deg,foo\n1,2,30,x\n", REQ_XY));
    TEST_ASSERT_EQUAL_STRING(" \"heading_deg\", \"foo\"; did you mean \"heading_deg\" -> heading_ref_deg (unit "
                             "deg)? (rename the header; units are not read from it); accepted names: t, mx, my, "
                             "mz, ax, ay, az, heading_ref_deg, cog_deg, speed_mps, glitch, outlier, roll_deg, "
                             "pitch_deg, yaw_deg, lat_deg, lon_deg, height_km, decimal_year, dop, gx, gy, gz",
                             g_d.note);
}

static void test_parse_duplicate_column_is_an_error(void)
{
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, parse("mx,my,MX\n1,2,3\n", REQ_XY));
    TEST_ASSERT_EQUAL_STRING("dump.csv:1:3: duplicate column \"mx\" (first at field 1)", g_err);
}

static void test_parse_field_count_mismatch_reports_truncation(void)
{
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, parse("t,mx,my,mz\n0,1,2,3\n0.1,1,2\n", REQ_XY));
    TEST_ASSERT_EQUAL_STRING("dump.csv:3:4: row has 3 fields but the header has 4 (truncated line?)",
                             g_err);
    magcal_replay_csv_free(&g_d);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, parse("mx,my\n1,2,\n", REQ_XY));
    TEST_ASSERT_EQUAL_STRING("dump.csv:2:3: row has 3 fields but the header has 2", g_err);
}

static void test_parse_truncated_file_at_every_byte_never_crashes(void)
{
    /* Every prefix of a valid dump either parses (to a prefix of its rows) or fails with a
     * message naming the file; a prefix never yields more rows than complete lines. */
    const char *text = "t,mx,my,mz\n0.000,-0.1758,-0.0637,nan\n0.402,-0.1876,-0.0210,nan\n"
                       "0.812,-0.1807,0.0106,nan\n";
    size_t len = strlen(text), cut, ok = 0u, bad = 0u;
    for (cut = 0u; cut <= len; ++cut) {
        char *copy = (char *)malloc(cut + 1u); /* exact-size heap copy: ASan sees overreads */
        magcal_status_t st;
        TEST_ASSERT_NOT_NULL(copy);
        memcpy(copy, text, cut);
        st = magcal_replay_csv_parse(copy, cut, "dump.csv", REQ_XY, &g_d, g_err, sizeof g_err);
        if (st == MAGCAL_OK) {
            size_t nl = 0u, i;
            for (i = 0u; i < cut; ++i) {
                nl += (copy[i] == '\n') ? 1u : 0u;
            }
            TEST_ASSERT_TRUE(g_d.n_rows <= nl); /* header line + rows, last maybe unterminated */
            ok++;
        } else {
            TEST_ASSERT_EQUAL_STRING_LEN("dump.csv:", g_err, 9);
            bad++;
        }
        magcal_replay_csv_free(&g_d);
        free(copy);
    }
    TEST_ASSERT_TRUE(ok > 0u);
    TEST_ASSERT_TRUE(bad > 0u);
}

static void test_parse_100kB_lines_error_or_parse_correctly(void)
{
    const size_t big = 100u * 1024u;
    char *text = (char *)malloc(big + 64u);
    size_t i;
    TEST_ASSERT_NOT_NULL(text);
    /* a 100 kB comment line is skipped */
    text[0] = '#';
    memset(text + 1, 'a', big);
    strcpy(text + 1 + big, "\nmx,my\n1,2\n");
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, parse(text, REQ_XY));
    ASSERT_SIZE(1u, g_d.n_rows);
    magcal_replay_csv_free(&g_d);
    /* a 100 kB numeric cell is rejected with a bounded message */
    strcpy(text, "mx,my\n1,");
    memset(text + 8, '7', big);
    strcpy(text + 8 + big, "\n");
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, parse(text, REQ_XY));
    TEST_ASSERT_EQUAL_STRING("dump.csv:2:2: number longer than 63 characters in column \"my\"", g_err);
    magcal_replay_csv_free(&g_d);
    /* a 100 kB line of commas: field count mismatch, not a crash */
    strcpy(text, "mx,my\n");
    for (i = 0u; i < big; ++i) {
        text[6u + i] = ',';
    }
    text[6u + big] = '\0';
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, parse(text, REQ_XY));
    TEST_ASSERT_EQUAL_STRING("dump.csv:2:3: row has 102401 fields but the header has 2", g_err);
    magcal_replay_csv_free(&g_d);
    /* a 100 kB run of letters in a recognised cell: quoted excerpt, ends with "..." */
    strcpy(text, "mx,my\n1,");
    memset(text + 8, 'z', big);
    text[8 + big] = '\0';
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, parse(text, REQ_XY));
    TEST_ASSERT_NOT_NULL(strstr(g_err, "zzzz...\" (column my)"));
    TEST_ASSERT_TRUE(strlen(g_err) < 120u);
    free(text);
}

static void test_parse_random_mutations_never_crash_and_always_explain(void)
{
    /* 3000 deterministic single/multi-byte mutations of a valid dump (xorshift32): each parse
     * either succeeds with at most the original row count, or fails with a "dump.csv:" message.
     * Run under ASan/UBSan in the host-asan preset. */
    static const char base[] = "# c\nt,mx,my,mz,heading_ref_deg,glitch\n0.0,-0.17,0.06,nan,,0\n"
                               "0.4,-0.18,0.02,nan,90,1\r\n0.8,1e-3,-2.5E+2,1,45.5,0\n";
    static const char alphabet[] = ",\n\r#\"e.-+0123456789nan \t\0x";
    uint32_t s = 12345u;
    size_t k, len = sizeof base - 1u, ok = 0u;
    for (k = 0u; k < 3000u; ++k) {
        char *buf = (char *)malloc(len);
        size_t m, nmut;
        magcal_status_t st;
        TEST_ASSERT_NOT_NULL(buf);
        memcpy(buf, base, len);
        s ^= s << 13;
        s ^= s >> 17;
        s ^= s << 5;
        nmut = 1u + s % 4u;
        for (m = 0u; m < nmut; ++m) {
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
            buf[s % len] = alphabet[(s >> 8) % (sizeof alphabet - 1u)];
        }
        st = magcal_replay_csv_parse(buf, (size_t)(s >> 20) % (len + 1u), "dump.csv", REQ_XY, &g_d,
                                     g_err, sizeof g_err);
        if (st == MAGCAL_OK) {
            TEST_ASSERT_TRUE(g_d.n_rows >= 1u && g_d.n_rows <= 3u);
            TEST_ASSERT_EQUAL_STRING("", g_err);
            ok++;
        } else {
            TEST_ASSERT_EQUAL_STRING_LEN("dump.csv:", g_err, 9);
        }
        magcal_replay_csv_free(&g_d);
        free(buf);
    }
    TEST_ASSERT_TRUE(ok > 0u);
}

static void test_parse_binary_and_empty_input_fail_cleanly(void)
{
    static const char bin[] = {'m', 'x', ',', 'm', 'y', '\n', '1', '\0', ',', '2', '\n'};
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG,
                          magcal_replay_csv_parse(bin, sizeof bin, "b.csv", REQ_XY, &g_d, g_err, sizeof g_err));
    TEST_ASSERT_EQUAL_STRING("b.csv:2: NUL byte in the line (binary file?)", g_err);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NO_DATA, parse("", REQ_XY));
    TEST_ASSERT_EQUAL_STRING("dump.csv: no header row (empty file, or only comments)", g_err);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NO_DATA, parse("# only\n\n", REQ_XY));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NO_DATA, parse("mx,my\n# nothing\n", REQ_XY));
    TEST_ASSERT_EQUAL_STRING("dump.csv: no data rows after the header", g_err);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_replay_csv_parse("x", 1u, "n", 0u, NULL, g_err, sizeof g_err));
}

static void test_parse_bom_and_tiny_error_buffer_are_safe(void)
{
    char tiny[8];
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, parse("\xEF\xBB\xBFmx,my\n1,2\n", REQ_XY));
    ASSERT_SIZE(1u, g_d.n_rows);
    magcal_replay_csv_free(&g_d);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG,
                          magcal_replay_csv_parse("mx,my\n1,x\n", 10u, "dump.csv", REQ_XY, &g_d, tiny, sizeof tiny));
    TEST_ASSERT_EQUAL_STRING("dump.cs", tiny);
}

static void test_read_missing_file_names_it(void)
{
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_PORT,
                          magcal_replay_csv_read("/nonexistent/x.csv", REQ_XY, &g_d, g_err, sizeof g_err));
    TEST_ASSERT_EQUAL_STRING("/nonexistent/x.csv: cannot open: No such file or directory", g_err);
}

static void test_read_bundled_dump_matches_its_known_first_row(void)
{
    /* tests/data/real/lsm9ds1_pmodnav_flat_turns.csv: 136 rows, first row
     * 0.000,-0.17579799999999995,-0.06372099999999983,nan (README of the dump). */
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK,
                          magcal_replay_csv_read(MAGCAL_SOURCE_DIR "/tests/data/real/lsm9ds1_pmodnav_flat_turns.csv",
                                                 REQ_XY, &g_d, g_err, sizeof g_err));
    ASSERT_SIZE(136u, g_d.n_rows);
    TEST_ASSERT_EQUAL_DOUBLE(-0.17579799999999995, g_d.col[MAGCAL_REPLAY_COL_MX][0]);
    TEST_ASSERT_EQUAL_DOUBLE(-0.06372099999999983, g_d.col[MAGCAL_REPLAY_COL_MY][0]);
    TEST_ASSERT_TRUE(isnan(g_d.col[MAGCAL_REPLAY_COL_MZ][0]));
}

static void test_plane_parses_pairs_and_rejects_others(void)
{
    magcal_replay_plane_t p = {{9u, 9u, 9u}};
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_replay_csv_plane("xz", &p));
    TEST_ASSERT_EQUAL_UINT(0u, p.src[0]);
    TEST_ASSERT_EQUAL_UINT(2u, p.src[1]);
    TEST_ASSERT_EQUAL_UINT(1u, p.src[2]);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_replay_csv_plane("ZY", &p));
    TEST_ASSERT_EQUAL_UINT(2u, p.src[0]);
    TEST_ASSERT_EQUAL_UINT(1u, p.src[1]);
    TEST_ASSERT_EQUAL_UINT(0u, p.src[2]);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_replay_csv_plane("XX", &p));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_replay_csv_plane("XYZ", &p));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_replay_csv_plane("AB", &p));
    TEST_ASSERT_EQUAL_UINT(2u, p.src[0]); /* untouched on failure */
}

static void test_fill_maps_plane_decimates_and_feeds_the_replay_port(void)
{
    const char *text = "t,mx,my,mz,ax,ay,az\n"
                       "100.0,1,2,3,0,0,1\n"
                       "100.5,4,5,6,0,0,1\n"
                       "101.0,7,8,9,0,0,1\n"
                       "101.5,10,11,12,0,0,1\n"
                       "102.25,13,14,15,0,0.5,1\n";
    magcal_vec3_t mag[3], acc[3], v;
    uint32_t t[3];
    magcal_replay_plane_t p;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, parse(text, REQ_XY));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_replay_csv_plane("XZ", &p));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_replay_csv_fill(&g_d, 0u, 3u, 2u, &p, mag, acc, t));
    TEST_ASSERT_EQUAL_FLOAT(1.0f, mag[0].x);
    TEST_ASSERT_EQUAL_FLOAT(3.0f, mag[0].y);
    TEST_ASSERT_EQUAL_FLOAT(2.0f, mag[0].z);
    TEST_ASSERT_EQUAL_FLOAT(13.0f, mag[2].x);
    TEST_ASSERT_EQUAL_FLOAT(15.0f, mag[2].y);
    TEST_ASSERT_EQUAL_FLOAT(1.0f, acc[2].y); /* az -> library y under XZ */
    TEST_ASSERT_EQUAL_FLOAT(0.5f, acc[2].z);
    TEST_ASSERT_EQUAL_UINT32(0u, t[0]);
    TEST_ASSERT_EQUAL_UINT32(1000u, t[1]);
    TEST_ASSERT_EQUAL_UINT32(2250u, t[2]);
    /* range checks: 3 rows with step 2 from row 1 would need row 5 */
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_replay_csv_fill(&g_d, 1u, 3u, 2u, &p, mag, NULL, NULL));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_replay_csv_fill(&g_d, 0u, 1u, 0u, &p, mag, NULL, NULL));
    /* the port serves exactly what was filled */
    magcal_port_replay_start(mag, acc, t, 3u, 0u);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_port_mag_read(&v));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_port_mag_read(&v));
    TEST_ASSERT_EQUAL_FLOAT(7.0f, v.x);
    TEST_ASSERT_EQUAL_UINT32(1000u, magcal_port_millis());
}

static void test_fill_two_axis_dump_zeroes_missing_z_and_rejects_missing_plane_axis(void)
{
    magcal_vec3_t mag[2];
    magcal_replay_plane_t p;
    uint32_t t[2];
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, parse("t,mx,my,mz\n1,1,2,nan\n0.5,3,4,\n", REQ_XY));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_replay_csv_fill(&g_d, 0u, 2u, 1u, NULL, mag, NULL, NULL));
    TEST_ASSERT_EQUAL_FLOAT(0.0f, mag[1].z);
    TEST_ASSERT_EQUAL_FLOAT(4.0f, mag[1].y);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_replay_csv_plane("XZ", &p));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE, magcal_replay_csv_fill(&g_d, 0u, 2u, 1u, &p, mag, NULL, NULL));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NO_DATA, magcal_replay_csv_fill(&g_d, 0u, 2u, 1u, NULL, mag, mag, NULL));
    /* time going backwards */
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_replay_csv_fill(&g_d, 0u, 2u, 1u, NULL, mag, NULL, t));
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_parse_any_column_order_extra_columns_comments_crlf_reads_values);
    RUN_TEST(test_parse_bad_number_names_file_line_and_field);
    RUN_TEST(test_parse_rejects_inf_hex_and_trailing_text);
    RUN_TEST(test_parse_garbage_in_unrecognised_column_is_ignored);
    RUN_TEST(test_parse_garbage_in_optional_recognised_column_is_an_error);
    RUN_TEST(test_parse_missing_cell_in_required_column_is_an_error);
    RUN_TEST(test_parse_missing_required_column_names_it);
    RUN_TEST(test_parse_missing_column_suggests_aliases);
    RUN_TEST(test_parse_semicolon_and_tab_separators_are_detected);
    RUN_TEST(test_parse_unknown_columns_are_described_in_the_note);
    RUN_TEST(test_parse_duplicate_column_is_an_error);
    RUN_TEST(test_parse_field_count_mismatch_reports_truncation);
    RUN_TEST(test_parse_truncated_file_at_every_byte_never_crashes);
    RUN_TEST(test_parse_100kB_lines_error_or_parse_correctly);
    RUN_TEST(test_parse_random_mutations_never_crash_and_always_explain);
    RUN_TEST(test_parse_binary_and_empty_input_fail_cleanly);
    RUN_TEST(test_parse_bom_and_tiny_error_buffer_are_safe);
    RUN_TEST(test_read_missing_file_names_it);
    RUN_TEST(test_read_bundled_dump_matches_its_known_first_row);
    RUN_TEST(test_plane_parses_pairs_and_rejects_others);
    RUN_TEST(test_fill_maps_plane_decimates_and_feeds_the_replay_port);
    RUN_TEST(test_fill_two_axis_dump_zeroes_missing_z_and_rejects_missing_plane_axis);
    RUN_TEST(test_parse_aided_columns_are_recognised_and_required_ones_checked);
    return UNITY_END();
}
