/* Minimal firmware-style consumer of the installed magcal package: check the build, restore the
 * stored calibration from its flash record, collect samples through the port, calibrate, adopt,
 * store the new record, and turn raw samples into headings. Memory is static and sized with the
 * library's macros (aligned by the declaration helpers); nothing is allocated.
 *
 *   consumer              the whole loop; the "flash page" starts blank (erased, 0xFF)
 *   consumer FILE.rec     firmware restore of a record exported by `magcal-replay
 *                         --export-record FILE.rec` (README "Storing a calibration"): validate,
 *                         use, print the heading of one port sample; exit 3 when refused */
#include <stdio.h>
#include <string.h>

#include "magcal.h"
#include "magcal/magcal_port.h"

#define CAPACITY 128u
#define SENSOR_ID 0x0001001Eu /* chosen by the firmware: e.g. part id 1, I2C address 0x1E */

static magcal_calibrator_t g_cal;
static magcal_vec2_t g_samples[CAPACITY];
static MAGCAL_CALIBRATOR_WORKSPACE_DECLARE(g_work, CAPACITY);
static uint8_t g_flash[MAGCAL_RECORD_LEN]; /* stands for the flash page that keeps the record */

/* Boot: the stored calibration when its record is intact, of this layout, 2-D and ours. */
static magcal_status_t restore(magcal_cal2d_t *cal)
{
    magcal_record_t rec;
    magcal_status_t st = magcal_record_unpack(g_flash, sizeof g_flash, &rec);
    if (st == MAGCAL_OK && (rec.kind != MAGCAL_RECORD_KIND_2D || rec.sensor_id != SENSOR_ID)) {
        st = MAGCAL_ERR_STATE; /* another sensor's (or a 3-D) record: not ours to use */
    }
    if (st == MAGCAL_OK) {
        *cal = rec.cal2d;
        printf("restored calibration of sensor 0x%08lX: %lu samples, est. heading error %.2f deg\n",
               (unsigned long)rec.sensor_id, (unsigned long)rec.n_used, (double)rec.est_heading_err_deg);
    } else {
        *cal = (magcal_cal2d_t)MAGCAL_CAL2D_IDENTITY;
        printf("no usable stored calibration (%s): start from identity\n", magcal_status_str(st));
    }
    return st;
}

static int print_heading(const magcal_cal2d_t *cal)
{
    magcal_vec3_t m;
    magcal_vec2_t raw;
    float mag_deg = 0.0f;
    float true_deg = 0.0f;
    magcal_status_t st;
    if (magcal_port_mag_read(&m) != MAGCAL_OK) {
        return 1;
    }
    raw.x = m.x;
    raw.y = m.y;
    st = magcal_heading_compute(cal, raw, -14.0f, &mag_deg, &true_deg);
    printf("heading: magnetic %.1f deg, true %.1f deg (%s)\n", (double)mag_deg, (double)true_deg,
           magcal_status_str(st));
    return st == MAGCAL_OK ? 0 : 1;
}

static int restore_file(const char *path)
{
    magcal_cal2d_t cal;
    FILE *f = fopen(path, "rb");
    size_t got = 0u;
    if (f != NULL) {
        got = fread(g_flash, 1u, sizeof g_flash, f);
        (void)fclose(f);
    }
    if (got != sizeof g_flash) {
        printf("%s: cannot read %u bytes\n", path, (unsigned)sizeof g_flash);
        return 3;
    }
    if (magcal_record_unpack(g_flash, sizeof g_flash, NULL) != MAGCAL_OK) {
        printf("%s: record refused: %s\n", path, magcal_status_str(magcal_record_validate(g_flash, sizeof g_flash)));
        return 3;
    }
    {
        magcal_record_t rec;
        (void)magcal_record_unpack(g_flash, sizeof g_flash, &rec);
        if (rec.kind != MAGCAL_RECORD_KIND_2D) {
            printf("%s: a 3-D record; this example uses 2-D headings\n", path);
            return 3;
        }
        cal = rec.cal2d;
        printf("%s: valid record of sensor 0x%08lX (%lu samples, radius %g, est. heading error %.2f deg)\n",
               path, (unsigned long)rec.sensor_id, (unsigned long)rec.n_used, (double)rec.radius,
               (double)rec.est_heading_err_deg);
    }
    return print_heading(&cal);
}

int main(int argc, char **argv)
{
    magcal_calibrator_cfg_t cfg = MAGCAL_CALIBRATOR_CFG_DEFAULT;
    magcal_cal_report_t report;
    magcal_record_t rec;
    magcal_cal2d_t current;
    magcal_status_t st;
    unsigned i;

    /* The library linked is the one these headers describe. Its configuration is checked by
     * every stateful init (MAGCAL_ERR_CONFIG_MISMATCH below); firmware that uses only stateless
     * calls checks it once with magcal_config_check(). */
    if (magcal_version() != MAGCAL_VERSION) {
        printf("magcal: headers %s, library %s\n", MAGCAL_VERSION_STRING, magcal_version_str());
        return 2;
    }
    if (argc > 1 && argv[1][0] != '\0') { /* (semihosting passes an empty argv[1]) */
        return restore_file(argv[1]);
    }
    memset(g_flash, 0xFF, sizeof g_flash); /* erased flash */
    (void)restore(&current);

    st = magcal_calibrator_init(&g_cal, &cfg, g_samples, CAPACITY, g_work, sizeof g_work);
    if (st != MAGCAL_OK) {
        printf("calibrator init: %s\n", magcal_status_str(st));
        return 2;
    }
    for (i = 0u; i < 400u && magcal_calibrator_count(&g_cal) < CAPACITY; ++i) {
        st = magcal_calibrator_poll(&g_cal); /* GATED (no new information) is an outcome, not a fault */
        if (!magcal_status_is_outcome(st)) {
            printf("poll: %s\n", magcal_status_str(st));
        }
    }
    st = magcal_calibrator_run(&g_cal, &current, &report);
    printf("magcal %s: calibration %s, %u samples used, coverage %.0f deg, est. heading error %.2f deg\n",
           magcal_version_str(), magcal_status_str(st), (unsigned)report.used,
           (double)report.coverage_deg, (double)report.est_heading_err_deg);
    if (st != MAGCAL_OK) {
        return 1; /* NOT_BETTER would be an outcome too, but this run starts from identity */
    }
    /* Adopted: store the record (erase + program the page), then "reboot" and restore it. */
    st = magcal_record_from_report(&rec, &report, SENSOR_ID, MAGCAL_RECORD_UNIT_RAW, 0u);
    if (st == MAGCAL_OK) {
        st = magcal_record_pack(&rec, g_flash, sizeof g_flash);
    }
    if (st != MAGCAL_OK || restore(&current) != MAGCAL_OK) {
        printf("record: %s\n", magcal_status_str(st));
        return 1;
    }
    return print_heading(&current);
}
