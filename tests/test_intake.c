/*
 * Tests of the intake store (src/intake/): synthetic 2-D drives and 3-D tumbles with known truth
 * (centre, field, headings), fixed seeds. Post-hoc checks bin the stored samples independently,
 * in double, around the TRUE centre (the test's own sector and igloo geometry).
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "magcal/calibrator.h"
#include "magcal/intake.h"
#include "intake/intake_internal.h" /* magcal_intake_drop_older: the continuous loop's cut */
#include "test_util.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

#define PI_D 3.14159265358979323846
#define D2R (PI_D / 180.0)
#define SECTORS 36u
#define PER_BIN 8u
#define BANDS 10u
#define PER_CELL 4u

static magcal_intake_slot_t g_slots[MAGCAL_INTAKE_SLOTS_2D(SECTORS, PER_BIN)];
static magcal_intake_slot_t g_slots_b[MAGCAL_INTAKE_SLOTS_2D(SECTORS, PER_BIN)];
static magcal_intake_slot_t g_slots3[MAGCAL_INTAKE_SLOTS_3D(BANDS, PER_CELL)];
static magcal_intake_t g_st;
static magcal_intake_t g_st_b;
static magcal_vec3_t g_out[MAGCAL_INTAKE_SLOTS_3D(BANDS, PER_CELL)];

/* Truth of the 2-D scenarios: hard iron (30, -20, 5) uT, mild soft iron, H = 20 uT, Z = -44 uT. */
static const double CX = 30.0, CY = -20.0, CZ = 5.0, H = 20.0, Z = -44.0;

/* Raw field at heading psi (deg) and pitch (deg) with noise sigma (uT) per axis. */
static magcal_vec3_t sample2(double psi_deg, double pitch_deg, double sigma, uint32_t *rng)
{
    const double p = psi_deg * D2R, th = pitch_deg * D2R;
    /* level body field: (-H sin psi, H cos psi, Z); pitch rotates y/z about x */
    const double hx = -H * sin(p), hy0 = H * cos(p);
    const double hy = hy0 * cos(th) + Z * sin(th), hz = -hy0 * sin(th) + Z * cos(th);
    magcal_vec3_t m;
    m.x = (float)(CX + 1.05 * hx + 0.03 * hy + sigma * test_rand_normal(rng));
    m.y = (float)(CY + 0.03 * hx + 0.95 * hy + sigma * test_rand_normal(rng));
    m.z = (float)(CZ + hz + sigma * test_rand_normal(rng));
    return m;
}

static void init2(magcal_intake_t *st, magcal_intake_slot_t *slots, const magcal_intake_cfg_t *cfg)
{
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_init(st, cfg, slots, MAGCAL_INTAKE_SLOTS_2D(SECTORS, PER_BIN)));
}

static void push_ok(magcal_intake_t *st, const magcal_vec3_t *m)
{
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_push(st, m, NULL));
}

/* Sector (test geometry, double) of a raw sample around the true centre. */
static unsigned sector_true(const magcal_vec3_t *m)
{
    double a = atan2(-((double)m->x - CX), (double)m->y - CY) / D2R;
    unsigned b;
    if (a < 0.0) {
        a += 360.0;
    }
    b = (unsigned)(a / (360.0 / SECTORS));
    return (b >= SECTORS) ? SECTORS - 1u : b;
}

/* Coverage (calibrator definition) of a sector occupancy table. */
static double coverage_of(const unsigned *occ, unsigned nb)
{
    unsigned best = 0, run = 0, i, s0 = nb;
    for (i = 0; i < nb; ++i) {
        if (occ[i]) {
            s0 = i + 1;
            break;
        }
    }
    if (s0 == nb && !occ[nb - 1]) {
        return 0.0;
    }
    for (i = 0; i < nb; ++i) {
        unsigned b = (s0 + i) % nb;
        run = occ[b] ? 0 : run + 1;
        best = (run > best) ? run : best;
    }
    return (double)(nb - best) * 360.0 / (double)nb;
}

/* Post-hoc: coverage of the stored samples around the true centre. */
static double posthoc_coverage2(const magcal_intake_t *st, unsigned *occ)
{
    size_t n = 0, i;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_snapshot3(st, g_out, sizeof(g_out) / sizeof(g_out[0]), &n));
    memset(occ, 0, SECTORS * sizeof(occ[0]));
    for (i = 0; i < n; ++i) {
        occ[sector_true(&g_out[i])]++;
    }
    return coverage_of(occ, SECTORS);
}

/* A drive of `turn_deg` at `rate` deg/s sampled at hz, from heading start. */
static void drive_arc(magcal_intake_t *st, double start, double turn_deg, double rate, double hz, uint32_t *rng)
{
    const size_t n = (size_t)(fabs(turn_deg) / rate * hz);
    size_t k;
    for (k = 0; k < n; ++k) {
        magcal_vec3_t m = sample2(start + turn_deg * (double)k / (double)n, 0.0, 0.1, rng);
        push_ok(st, &m);
    }
}

static void test_intake_init_validates_config_and_storage(void)
{
    magcal_intake_cfg_t cfg = MAGCAL_INTAKE_CFG_DEFAULT_2D;
    uint16_t nb = 0;
    unsigned bands;
    TEST_ASSERT_EQUAL_UINT32((uint32_t)(288u), (uint32_t)(MAGCAL_INTAKE_SLOTS_2D(36u, 8u)));
    TEST_ASSERT_EQUAL_UINT32((uint32_t)(2u), (uint32_t)(MAGCAL_INTAKE_MASK_WORDS(36u)));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_intake_init(NULL, &cfg, g_slots, 288u));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_intake_init(&g_st, NULL, g_slots, 288u));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_intake_init(&g_st, &cfg, NULL, 288u));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_WORKSPACE, magcal_intake_init(&g_st, &cfg, g_slots, 287u));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_init(&g_st, &cfg, g_slots, 288u));
    cfg.bins = 7u;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_intake_init(&g_st, &cfg, g_slots, 288u));
    cfg.bins = 36u;
    cfg.per_bin = 0u;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_intake_init(&g_st, &cfg, g_slots, 288u));
    cfg.per_bin = 8u;
    cfg.min_spacing_rel = NAN;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_intake_init(&g_st, &cfg, g_slots, 288u));
    cfg.min_spacing_rel = 0.02f;
    cfg.recentre_rel = 0.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_intake_init(&g_st, &cfg, g_slots, 288u));
    cfg.recentre_rel = 0.05f;
    cfg.range_limit = -1.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_intake_init(&g_st, &cfg, g_slots, 288u));
    cfg.range_limit = 0.0f;
    cfg.sweep_steps = 0u;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_intake_init(&g_st, &cfg, g_slots, 288u));
    cfg.sweep_steps = 8u;
    cfg.dims = 4u;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_intake_init(&g_st, &cfg, g_slots, 288u));
    /* 3-D: the exact cell count of every band count against an independent count (double) and the
     * bound macro; 10 bands = 128 cells, the default */
    cfg.dims = 3u;
    for (bands = 4u; bands <= MAGCAL_INTAKE_MAX_BANDS; ++bands) {
        unsigned b, total = 0;
        for (b = 0; b < bands; ++b) {
            long c = lround(2.0 * bands * sin(((double)b + 0.5) * PI_D / bands));
            total += (unsigned)((c < 1) ? 1 : c);
        }
        cfg.bins = (uint16_t)bands;
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_bins(&cfg, &nb));
        TEST_ASSERT_EQUAL_UINT(total, nb);
        TEST_ASSERT_TRUE(nb <= MAGCAL_INTAKE_CELLS_3D_MAX(bands));
        TEST_ASSERT_TRUE(nb <= MAGCAL_INTAKE_MAX_BINS);
    }
    cfg.bins = 10u;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_bins(&cfg, &nb));
    TEST_ASSERT_EQUAL_UINT(128u, nb); /* the default mask */
    cfg.bins = 3u;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_intake_bins(&cfg, &nb));
    cfg.bins = MAGCAL_INTAKE_MAX_BANDS + 1u;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_intake_bins(&cfg, &nb));
}

static void test_intake_bad_calls_return_status(void)
{
    magcal_intake_cfg_t cfg = MAGCAL_INTAKE_CFG_DEFAULT_2D;
    magcal_intake_progress_t p;
    magcal_intake_counters_t c;
    magcal_vec3_t m = {1.0f, 2.0f, 3.0f};
    magcal_vec2_t o2[4];
    uint32_t words[2];
    size_t n = 99;
    memset(&g_st, 0, sizeof(g_st));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NOT_INITIALISED, magcal_intake_push(&g_st, &m, NULL));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NOT_INITIALISED, magcal_intake_progress(&g_st, &p));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NOT_INITIALISED, magcal_intake_reset(&g_st));
    init2(&g_st, g_slots, &cfg);
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_intake_push(NULL, &m, NULL));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_intake_push(&g_st, NULL, NULL));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_intake_progress(&g_st, NULL));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_intake_counters(&g_st, NULL));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_intake_snapshot2(&g_st, NULL, 4u, &n));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NULL, magcal_intake_snapshot2(&g_st, o2, 4u, NULL));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_WORKSPACE, magcal_intake_mask(&g_st, words, 1u));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_intake_set_centre(&g_st, &m, 0.0f));
    m.x = INFINITY;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE, magcal_intake_set_centre(&g_st, &m, 1.0f));
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE, magcal_intake_push(&g_st, &m, NULL));
    m.x = NAN;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_NONFINITE, magcal_intake_push(&g_st, &m, NULL));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_counters(&g_st, &c));
    TEST_ASSERT_EQUAL_UINT32(2u, c.refused_nonfinite);
    TEST_ASSERT_EQUAL_UINT32(0u, c.stored);
    /* a snapshot that does not fit writes nothing */
    {
        uint32_t rng = 3u;
        drive_arc(&g_st, 0.0, 90.0, 20.0, 50.0, &rng);
    }
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_WORKSPACE, magcal_intake_snapshot2(&g_st, o2, 4u, &n));
    TEST_ASSERT_EQUAL_UINT32((uint32_t)(99u), (uint32_t)(n));
}

static void test_intake_newest_replaces_oldest_in_its_bin(void)
{
    /* 12 samples inside one 10-degree sector (raw angles 2.0 .. 7.5 deg around the installed
     * centre, radius 20, 0.17 uT apart), cap 4 per bin */
    magcal_intake_cfg_t cfg = MAGCAL_INTAKE_CFG_DEFAULT_2D;
    const magcal_vec3_t c = {(float)CX, (float)CY, (float)CZ};
    magcal_intake_counters_t ctr;
    magcal_intake_outcome_t oc;
    magcal_vec3_t seq[12];
    size_t n = 0, i;
    cfg.per_bin = 4u;
    cfg.min_spacing_rel = 0.004f; /* 0.08 uT, 0.16 uT in a full bin */
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_init(&g_st, &cfg, g_slots, 144u));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_set_centre(&g_st, &c, (float)H));
    for (i = 0; i < 12; ++i) {
        const double a = (2.0 + 0.5 * (double)i) * D2R; /* raw angle atan2(-ux, uy) */
        seq[i].x = (float)(CX - H * sin(a));
        seq[i].y = (float)(CY + H * cos(a));
        seq[i].z = (float)CZ;
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_push(&g_st, &seq[i], &oc));
        TEST_ASSERT_EQUAL_INT((i < 4u) ? MAGCAL_INTAKE_STORED : MAGCAL_INTAKE_REPLACED, oc);
    }
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_counters(&g_st, &ctr));
    TEST_ASSERT_EQUAL_UINT32(4u, ctr.stored);
    TEST_ASSERT_EQUAL_UINT32(4u, ctr.added);
    TEST_ASSERT_EQUAL_UINT32(8u, ctr.replaced);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_snapshot3(&g_st, g_out, 16u, &n));
    TEST_ASSERT_EQUAL_UINT32(4u, (uint32_t)n);
    for (i = 8; i < 12; ++i) { /* exactly the four newest, whatever their slot order */
        size_t k, found = 0;
        for (k = 0; k < n; ++k) {
            found += (memcmp(&g_out[k], &seq[i], sizeof(seq[i])) == 0) ? 1u : 0u;
        }
        TEST_ASSERT_EQUAL_UINT32(1u, (uint32_t)found);
    }
    /* a repeat of the newest is refused for spacing and changes nothing */
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_push(&g_st, &seq[11], &oc));
    TEST_ASSERT_EQUAL_INT(MAGCAL_INTAKE_REFUSED_SPACING, oc);
}

static void test_intake_saturated_samples_refused_and_counted(void)
{
    magcal_intake_cfg_t cfg = MAGCAL_INTAKE_CFG_DEFAULT_2D;
    magcal_intake_counters_t ctr;
    magcal_intake_outcome_t oc;
    uint32_t rng = 5u;
    size_t k;
    cfg.range_limit = 60.0f; /* a +-60 uT sensor; the ring reaches |x| ~ 51 */
    init2(&g_st, g_slots, &cfg);
    for (k = 0; k < 2000; ++k) {
        magcal_vec3_t m = sample2(360.0 * (double)k / 500.0, 0.0, 0.1, &rng);
        magcal_status_t s;
        if (k % 10u == 3u) { /* a magnet: one axis pinned at the rail */
            m.y = ((k % 20u) == 3u) ? 60.0f : -60.0f;
        }
        s = magcal_intake_push(&g_st, &m, &oc);
        if (k % 10u == 3u) {
            TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_SATURATED, s);
            TEST_ASSERT_EQUAL_INT(MAGCAL_INTAKE_REFUSED_SATURATED, oc);
        } else {
            TEST_ASSERT_EQUAL_INT(MAGCAL_OK, s);
        }
    }
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_counters(&g_st, &ctr));
    TEST_ASSERT_EQUAL_UINT32(200u, ctr.refused_saturated);
    TEST_ASSERT_EQUAL_UINT32(2000u, ctr.pushed);
    {
        size_t n = 0, i;
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_snapshot3(&g_st, g_out, 288u, &n));
        for (i = 0; i < n; ++i) {
            TEST_ASSERT_TRUE(fabsf(g_out[i].y) < 60.0f);
        }
    }
}

static void test_intake_spike_in_first_sample_does_not_move_centre(void)
{
    magcal_intake_cfg_t cfg = MAGCAL_INTAKE_CFG_DEFAULT_2D;
    magcal_intake_progress_t p;
    unsigned occ[SECTORS];
    const magcal_vec3_t spike = {900.0f, -700.0f, 400.0f};
    double bb_lo[2] = {spike.x, spike.y}, bb_hi[2] = {spike.x, spike.y};
    uint32_t rng = 21u;
    size_t k;
    init2(&g_st, g_slots, &cfg);
    push_ok(&g_st, &spike);
    for (k = 0; k < 3000; ++k) { /* 1.5 turns at 50 Hz, 9 deg/s */
        magcal_vec3_t m = sample2(0.18 * (double)k, 0.0, 0.1, &rng);
        push_ok(&g_st, &m);
        bb_lo[0] = fmin(bb_lo[0], m.x);
        bb_hi[0] = fmax(bb_hi[0], m.x);
        bb_lo[1] = fmin(bb_lo[1], m.y);
        bb_hi[1] = fmax(bb_hi[1], m.y);
    }
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_settle(&g_st));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_progress(&g_st, &p));
    TEST_ASSERT_EQUAL_INT(MAGCAL_INTAKE_CENTRE_PROVISIONAL, p.centre_source);
    /* the provisional centre: within 3 % of R of the truth (soft iron 1.05/0.95 included);
     * the bounding-box midpoint of the same samples is ~400 uT off */
    TEST_ASSERT_FLOAT_WITHIN(0.03f * (float)H, (float)CX, p.centre.x);
    TEST_ASSERT_FLOAT_WITHIN(0.03f * (float)H, (float)CY, p.centre.y);
    TEST_ASSERT_TRUE(fabs(0.5 * (bb_lo[0] + bb_hi[0]) - CX) > 300.0);
    TEST_ASSERT_FLOAT_WITHIN(0.1f * (float)H, (float)H, p.radius);
    TEST_ASSERT_EQUAL_FLOAT(360.0f, p.coverage_deg);
    TEST_ASSERT_EQUAL_DOUBLE(360.0, posthoc_coverage2(&g_st, occ));
}

/* An hour at 50 Hz on the host. On the QEMU target (cortex-m4f-tests preset) the test's double
 * generator runs in software double: the hour took ~60 s per test there, against the 120 s
 * limit of one on-target run, so the target variant drives 10 minutes (the hills' full period,
 * the lane-change wander twice) with the same per-sample bounds. */
#if defined(__arm__)
#define LONG_N 30000u
#else
#define LONG_N 180000u
#endif

static void test_intake_parked_hour_fills_only_its_own_bin(void)
{
    /* one turn to settle the centre, then 180 000 samples (an hour at 50 Hz) parked at 137 deg
     * with 0.15 uT noise: only the parked sector (and, by noise, a neighbour) may change */
    magcal_intake_cfg_t cfg = MAGCAL_INTAKE_CFG_DEFAULT_2D;
    magcal_intake_counters_t c0, c1;
    unsigned occ0[SECTORS], occ1[SECTORS], i;
    static magcal_vec3_t before[288];
    size_t n0 = 0, n1 = 0, k;
    uint32_t rng = 7u;
    const magcal_vec3_t parked_dir = sample2(137.0, 0.0, 0.0, &rng);
    const unsigned sb = sector_true(&parked_dir);
    init2(&g_st, g_slots, &cfg);
    drive_arc(&g_st, 0.0, 360.0, 15.0, 50.0, &rng);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_settle(&g_st));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_counters(&g_st, &c0));
    (void)posthoc_coverage2(&g_st, occ0);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_snapshot3(&g_st, before, 288u, &n0));
    for (k = 0; k < LONG_N; ++k) {
        magcal_vec3_t m = sample2(137.0, 0.0, 0.15, &rng);
        push_ok(&g_st, &m);
    }
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_counters(&g_st, &c1));
    (void)posthoc_coverage2(&g_st, occ1);
    for (i = 0; i < SECTORS; ++i) {
        unsigned d = (i + SECTORS - sb) % SECTORS;
        if (d > 1u && d < SECTORS - 1u) {
            TEST_ASSERT_EQUAL_UINT(occ0[i], occ1[i]); /* every other sector untouched */
        }
    }
    /* the noise cloud (0.15 uT vs a 0.4 uT spacing) churns within its own bins; most parked
     * samples are refused for spacing */
    printf("parked: added %u replaced %u refused %u\n", (unsigned)(c1.added - c0.added),
           (unsigned)(c1.replaced - c0.replaced), (unsigned)(c1.refused_spacing - c0.refused_spacing));
    TEST_ASSERT_TRUE(c1.refused_spacing - c0.refused_spacing >= LONG_N - LONG_N / 20u);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_snapshot3(&g_st, g_out, 288u, &n1));
    TEST_ASSERT_TRUE(n1 >= n0 - PER_BIN && n1 <= n0 + PER_BIN);
    /* parked from power-up: one or two sectors, at most two bins of samples */
    init2(&g_st, g_slots, &cfg);
    for (k = 0; k < LONG_N; ++k) {
        magcal_vec3_t m = sample2(137.0, 0.0, 0.15, &rng);
        push_ok(&g_st, &m);
    }
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_counters(&g_st, &c1));
    TEST_ASSERT_TRUE(c1.stored <= 2u * PER_BIN);
    {
        magcal_intake_progress_t p;
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_progress(&g_st, &p));
        TEST_ASSERT_TRUE(p.bins_filled <= 2u);
        TEST_ASSERT_TRUE(p.coverage_deg <= 20.0f);
    }
}

static void test_intake_straight_hour_with_hills_fills_only_its_own_bins(void)
{
    /* 180 000 samples: heading 250 +- 1.5 deg (lane changes, road curvature), pitch +-6 deg
     * hills (10-minute period), 0.15 uT noise; 2-D and 3-D stores */
    magcal_intake_cfg_t cfg = MAGCAL_INTAKE_CFG_DEFAULT_2D;
    magcal_intake_cfg_t cfg3 = MAGCAL_INTAKE_CFG_DEFAULT_3D;
    magcal_intake_progress_t p, p3;
    unsigned occ[SECTORS], i, nocc = 0;
    uint32_t rng = 8u;
    size_t k;
    init2(&g_st, g_slots, &cfg);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_init(&g_st_b, &cfg3, g_slots3, MAGCAL_INTAKE_SLOTS_3D(BANDS, PER_CELL)));
    for (k = 0; k < LONG_N; ++k) {
        const double t = (double)k / 50.0;
        const double psi = 250.0 + 1.5 * sin(t / 40.0), pitch = 6.0 * sin(2.0 * PI_D * t / 600.0);
        magcal_vec3_t m = sample2(psi, pitch, 0.15, &rng);
        push_ok(&g_st, &m);
        push_ok(&g_st_b, &m);
    }
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_progress(&g_st, &p));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_progress(&g_st_b, &p3));
    (void)posthoc_coverage2(&g_st, occ);
    for (i = 0; i < SECTORS; ++i) {
        nocc += occ[i] ? 1u : 0u;
    }
    printf("straight: 2d filled %u stored %u nocc %u; 3d filled %u stored %u\n", (unsigned)p.bins_filled, (unsigned)p.stored, nocc, (unsigned)p3.bins_filled, (unsigned)p3.stored);
    /* 2-D: the heading's sector(s) (+-1.5 deg, plus the hills' tilt error) */
    TEST_ASSERT_TRUE(p.bins_filled <= 3u);
    TEST_ASSERT_TRUE(nocc <= 3u);
    TEST_ASSERT_TRUE(p.stored <= 3u * PER_BIN);
    /* 3-D: 12 deg of pitch sweep a short track on the sphere: a few of 128 cells */
    TEST_ASSERT_TRUE(p3.bins_filled <= 6u);
    TEST_ASSERT_TRUE(p3.stored <= 6u * PER_CELL);
}

static void test_intake_progress_agrees_with_posthoc_coverage(void)
{
    /* arcs of 120..360 deg from random starts, 10, 50 and 100 Hz, turn rate 5..25 deg/s: live
     * coverage vs the stored samples binned around the TRUE centre: within one sector */
    static const double rates_hz[3] = {10.0, 50.0, 100.0};
    magcal_intake_cfg_t cfg = MAGCAL_INTAKE_CFG_DEFAULT_2D;
    uint32_t rng = 1234u;
    unsigned trial, worst_bins = 0;
    double worst_arc = 0.0;
    for (trial = 0; trial < 30; ++trial) {
        const double hz = rates_hz[trial % 3u];
        const double arc = 120.0 + 240.0 * test_rand_uniform(&rng);
        const double start = 360.0 * test_rand_uniform(&rng);
        const double rate = 5.0 + 20.0 * test_rand_uniform(&rng);
        magcal_intake_progress_t p;
        unsigned occ[SECTORS];
        double post, exact;
        init2(&g_st, g_slots, &cfg);
        drive_arc(&g_st, start, arc, rate, hz, &rng);
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_settle(&g_st));
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_progress(&g_st, &p));
        post = posthoc_coverage2(&g_st, occ);
        TEST_ASSERT_EQUAL_INT(MAGCAL_INTAKE_CENTRE_PROVISIONAL, p.centre_source);
        TEST_ASSERT_TRUE(fabs((double)p.coverage_deg - post) <= 10.0 + 1e-3);
        /* and within two sectors (bin rounding at both ends) of the arc actually driven */
        exact = arc;
        worst_arc = fmax(worst_arc, exact - post);
        TEST_ASSERT_EQUAL_FLOAT(360.0f - p.coverage_deg, p.missing_width_deg);
        worst_bins += (fabs((double)p.coverage_deg - post) > 1e-3) ? 1u : 0u;
        TEST_ASSERT_TRUE(p.completion_pct >= 0.0f && p.completion_pct <= 100.0f);
    }
    printf("progress: %u of 30 trials one sector off the post-hoc coverage, none more\n", worst_bins);
    /* known limitation (docs/calibrator.md, "Intake store"): before the first usable ring fit the
     * bins are around the raw origin, which crowds the first ~100 degrees into few bins; measured
     * at most 53 deg of the driven arc lost in these 30 trials */
    printf("progress: largest driven arc not in the store %.1f deg\n", worst_arc);
    TEST_ASSERT_TRUE(worst_arc <= 60.0);
}

static void test_intake_rate_independent_defaults(void)
{
    /* the same two turns at 10 Hz and at 100 Hz: the same coverage, stored counts within 2x */
    magcal_intake_cfg_t cfg = MAGCAL_INTAKE_CFG_DEFAULT_2D;
    magcal_intake_progress_t p10, p100;
    uint32_t rng = 99u;
    init2(&g_st, g_slots, &cfg);
    drive_arc(&g_st, 10.0, 720.0, 20.0, 10.0, &rng);
    init2(&g_st_b, g_slots_b, &cfg);
    drive_arc(&g_st_b, 10.0, 720.0, 20.0, 100.0, &rng);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_settle(&g_st));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_settle(&g_st_b));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_progress(&g_st, &p10));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_progress(&g_st_b, &p100));
    TEST_ASSERT_EQUAL_FLOAT(360.0f, p10.coverage_deg);
    TEST_ASSERT_EQUAL_FLOAT(360.0f, p100.coverage_deg);
    TEST_ASSERT_TRUE(p10.stored >= 100u && p100.stored >= 100u);
    TEST_ASSERT_TRUE(p100.stored <= 2u * p10.stored && p10.stored <= 2u * p100.stored);
}

/* Independent igloo cell (double) of a direction u. */
static unsigned igloo_cell(const double u[3], unsigned bands)
{
    double r = sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
    double th = acos(u[2] / r), ph = atan2(u[1], u[0]);
    unsigned b = (unsigned)(th / (PI_D / bands)), k, start = 0, i, cells = 0;
    b = (b >= bands) ? bands - 1u : b;
    for (i = 0; i <= b; ++i) {
        long c = lround(2.0 * bands * sin(((double)i + 0.5) * PI_D / bands));
        cells = (unsigned)((c < 1) ? 1 : c);
        if (i < b) {
            start += cells;
        }
    }
    if (ph < 0.0) {
        ph += 2.0 * PI_D;
    }
    k = (unsigned)(ph / (2.0 * PI_D) * cells);
    k = (k >= cells) ? cells - 1u : k;
    return start + k;
}

static void test_intake_3d_tumble_coverage_mask(void)
{
    /* a slow random tumble (orientation random walk) of a 3-D sensor with hard iron (40, -25, 60)
     * and radius 48 uT, 50 Hz; first only the upper hemisphere of directions, then all */
    static const double c3[3] = {40.0, -25.0, 60.0};
    magcal_intake_cfg_t cfg = MAGCAL_INTAKE_CFG_DEFAULT_3D;
    magcal_intake_progress_t p;
    uint32_t mask[MAGCAL_INTAKE_MASK_WORDS(MAGCAL_INTAKE_CELLS_3D_MAX(BANDS))];
    unsigned post[MAGCAL_INTAKE_CELLS_3D_MAX(BANDS)];
    double d[3] = {0.0, 0.0, 1.0};
    uint32_t rng = 4242u;
    unsigned phase, i, diff;
    uint16_t ncell = 0;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_bins(&cfg, &ncell));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_init(&g_st_b, &cfg, g_slots3, MAGCAL_INTAKE_SLOTS_3D(BANDS, PER_CELL)));
    for (phase = 0; phase < 2; ++phase) {
        size_t k, n = 0;
        for (k = 0; k < 30000u; ++k) {
            magcal_vec3_t m;
            double nrm;
            for (i = 0; i < 3; ++i) {
                d[i] += 0.02 * test_rand_normal(&rng);
            }
            if (phase == 0 && d[2] < 0.05) {
                d[2] = 0.05 + fabs(d[2]);
            }
            nrm = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
            for (i = 0; i < 3; ++i) {
                d[i] /= nrm;
            }
            m.x = (float)(c3[0] + 48.0 * d[0] + 0.1 * test_rand_normal(&rng));
            m.y = (float)(c3[1] + 48.0 * d[1] + 0.1 * test_rand_normal(&rng));
            m.z = (float)(c3[2] + 48.0 * d[2] + 0.1 * test_rand_normal(&rng));
            push_ok(&g_st_b, &m);
        }
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_settle(&g_st_b));
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_progress(&g_st_b, &p));
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_mask(&g_st_b, mask, sizeof(mask) / sizeof(mask[0])));
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_snapshot3(&g_st_b, g_out, sizeof(g_out) / sizeof(g_out[0]), &n));
        memset(post, 0, sizeof(post));
        for (k = 0; k < n; ++k) {
            double u[3] = {g_out[k].x - c3[0], g_out[k].y - c3[1], g_out[k].z - c3[2]};
            post[igloo_cell(u, BANDS)]++;
        }
        diff = 0;
        for (i = 0; i < ncell; ++i) {
            unsigned live = (mask[i / 32u] >> (i % 32u)) & 1u;
            diff += (live != (post[i] ? 1u : 0u)) ? 1u : 0u;
        }
        printf("3d phase %u: cells differing from post-hoc %u of %u, fill %.3f, completion %.1f %%\n", phase, diff,
               (unsigned)ncell, (double)p.fill_fraction, (double)p.completion_pct);
        /* the live mask is the post-hoc one up to cells on the edge of the provisional centre's error */
        TEST_ASSERT_TRUE(diff <= ncell / 20u);
        if (phase == 0) {
            /* upper hemisphere only: the lower bands (colatitude > 100 deg) are empty */
            TEST_ASSERT_TRUE(p.fill_fraction > 0.40f && p.fill_fraction < 0.62f);
            TEST_ASSERT_TRUE(p.completion_pct < 62.0f);
        } else {
            TEST_ASSERT_TRUE(p.fill_fraction > 0.90f);
            TEST_ASSERT_TRUE(p.completion_pct > 85.0f);
            /* the provisional centre of a full sphere: within 2 % of R */
            TEST_ASSERT_FLOAT_WITHIN(1.0f, (float)c3[0], p.centre.x);
            TEST_ASSERT_FLOAT_WITHIN(1.0f, (float)c3[1], p.centre.y);
            TEST_ASSERT_FLOAT_WITHIN(1.0f, (float)c3[2], p.centre.z);
        }
    }
}

static void test_intake_installed_centre_rebins_store(void)
{
    /* collected around the origin guess of a store fed a half turn: installing the true centre
     * re-bins every sample; afterwards the live sectors are the post-hoc ones exactly */
    magcal_intake_cfg_t cfg = MAGCAL_INTAKE_CFG_DEFAULT_2D;
    const magcal_vec3_t c = {(float)CX, (float)CY, (float)CZ};
    magcal_intake_progress_t p;
    magcal_intake_counters_t ctr;
    unsigned occ[SECTORS], i;
    uint32_t words[MAGCAL_INTAKE_MASK_WORDS(SECTORS)];
    uint32_t rng = 17u;
    init2(&g_st, g_slots, &cfg);
    drive_arc(&g_st, 30.0, 200.0, 10.0, 50.0, &rng);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_set_centre(&g_st, &c, (float)H));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_progress(&g_st, &p));
    TEST_ASSERT_EQUAL_UINT8(1u, p.rebinning);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_settle(&g_st));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_progress(&g_st, &p));
    TEST_ASSERT_EQUAL_UINT8(0u, p.rebinning);
    TEST_ASSERT_EQUAL_INT(MAGCAL_INTAKE_CENTRE_INSTALLED, p.centre_source);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_counters(&g_st, &ctr));
    TEST_ASSERT_TRUE(ctr.rebinned > 0u);
    (void)posthoc_coverage2(&g_st, occ);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_mask(&g_st, words, 2u));
    for (i = 0; i < SECTORS; ++i) {
        TEST_ASSERT_EQUAL_UINT((occ[i] != 0u) ? 1u : 0u, (words[i / 32u] >> (i % 32u)) & 1u);
    }
    /* the installed centre is kept: further pushes never move it */
    drive_arc(&g_st, 220.0, 360.0, 10.0, 50.0, &rng); /* a full turn: every sector around the installed centre */
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_progress(&g_st, &p));
    TEST_ASSERT_EQUAL_FLOAT((float)CX, p.centre.x);
    TEST_ASSERT_EQUAL_FLOAT((float)CY, p.centre.y);
    TEST_ASSERT_EQUAL_FLOAT(360.0f, p.coverage_deg);
    /* reset drops everything */
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_reset(&g_st));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_progress(&g_st, &p));
    TEST_ASSERT_EQUAL_UINT32(0u, p.stored);
    TEST_ASSERT_EQUAL_INT(MAGCAL_INTAKE_CENTRE_NONE, p.centre_source);
}

static void test_intake_same_stream_same_store(void)
{
    magcal_intake_cfg_t cfg = MAGCAL_INTAKE_CFG_DEFAULT_2D;
    magcal_intake_counters_t a, b;
    uint32_t r1 = 555u, r2 = 555u;
    size_t na = 0, nb = 0;
    static magcal_vec3_t outb[288];
    init2(&g_st, g_slots, &cfg);
    init2(&g_st_b, g_slots_b, &cfg);
    drive_arc(&g_st, 0.0, 500.0, 12.0, 50.0, &r1);
    drive_arc(&g_st_b, 0.0, 500.0, 12.0, 50.0, &r2);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_counters(&g_st, &a));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_counters(&g_st_b, &b));
    TEST_ASSERT_EQUAL_MEMORY(&a, &b, sizeof(a));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_snapshot3(&g_st, g_out, 288u, &na));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_snapshot3(&g_st_b, outb, 288u, &nb));
    TEST_ASSERT_EQUAL_UINT32((uint32_t)(na), (uint32_t)(nb));
    TEST_ASSERT_EQUAL_MEMORY(g_out, outb, na * sizeof(g_out[0]));
    /* after reset the same stream gives the same store again */
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_reset(&g_st_b));
    r2 = 555u;
    drive_arc(&g_st_b, 0.0, 500.0, 12.0, 50.0, &r2);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_snapshot3(&g_st_b, outb, 288u, &nb));
    TEST_ASSERT_EQUAL_UINT32((uint32_t)(na), (uint32_t)(nb));
    TEST_ASSERT_EQUAL_MEMORY(g_out, outb, na * sizeof(g_out[0]));
}

/* The solver's coverage of the store's samples (magcal_calibrator_run, default configuration,
 * nothing installed); its status through *st. */
static MAGCAL_CALIBRATOR_WORKSPACE_DECLARE(g_work, MAGCAL_INTAKE_SLOTS_2D(SECTORS, PER_BIN));
static magcal_vec2_t g_buf2[MAGCAL_INTAKE_SLOTS_2D(SECTORS, PER_BIN)];
static magcal_vec2_t g_solve2[MAGCAL_INTAKE_SLOTS_2D(SECTORS, PER_BIN)];
static float solver_coverage(const magcal_intake_t *st, magcal_status_t *status)
{
    static magcal_calibrator_t cal;
    const magcal_calibrator_cfg_t cfg = MAGCAL_CALIBRATOR_CFG_DEFAULT;
    magcal_cal2d_t cur = MAGCAL_CAL2D_IDENTITY;
    magcal_cal_report_t rep;
    size_t n = 0u;
    size_t i;
    const size_t cap = sizeof(g_solve2) / sizeof(g_solve2[0]);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_snapshot2(st, g_solve2, cap, &n));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_calibrator_init(&cal, &cfg, g_buf2, cap, g_work, sizeof g_work));
    for (i = 0u; i < n; ++i) {
        (void)magcal_calibrator_push(&cal, g_solve2[i]);
    }
    *status = magcal_calibrator_run(&cal, &cur, &rep);
    return rep.coverage_deg;
}

static void test_intake_progress_coverage_agrees_with_solver_despite_spikes(void)
{
    /* gen_drive's start: a spike in row 0 (350, -420, 510), then a turn (+-2 deg of pitch, 0.15 uT
     * noise, 0.5 deg per sample) from heading 300 through 0 to 300 + 400, with a burst of 8
     * garbage samples (uniform +-600 uT) 150 degrees into it. The spike sits at 219 deg around
     * the true centre, inside the 150..300 gap of the first 210 degrees: counted, it split that
     * gap and the live coverage read ~280 where the solver found ~210 (gen_drive seed 3: 8 of 17
     * solves failed COVERAGE). Required: after 210 degrees the live coverage is at most 230; every
     * 10 pushes once it reaches 200, the solver is run on the store (default configuration) and,
     * where it adopts (its coverage: corrected headings of its inliers), the live value is within
     * one sector per edge of the gap (20 deg): the store bins raw headings around its provisional
     * centre, the solver corrected ones, and soft iron and the centre's error shift each edge by a
     * few degrees. The share within one sector is printed with the largest difference over every
     * solve that reports a coverage (a COVERAGE failure included: there the solver's own fit of a
     * partial arc can be far off, 270 live / 190 solver once here). */
    const magcal_intake_cfg_t cfg = MAGCAL_INTAKE_CFG_DEFAULT_2D;
    const magcal_vec3_t spike = {350.0f, -420.0f, 510.0f};
    uint32_t rng = 0x5eed0013u;
    unsigned k;
    unsigned compared = 0u;
    unsigned started = 0u;
    unsigned failed_cov = 0u;
    unsigned within1 = 0u;
    unsigned adopted = 0u;
    double worst = 0.0;
    init2(&g_st, g_slots, &cfg);
    push_ok(&g_st, &spike);
    for (k = 0u; k <= 800u; ++k) {
        const double psi = 300.0 + 0.5 * (double)k;
        const magcal_vec3_t m = sample2(fmod(psi, 360.0), 2.0 * sin(0.01 * (double)k), 0.15, &rng);
        magcal_intake_progress_t p;
        push_ok(&g_st, &m);
        if (k == 420u) { /* 210 degrees driven (300 .. 150): the spike at 219 must not bridge the gap */
            TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_progress(&g_st, &p));
            TEST_ASSERT_TRUE_MESSAGE(p.coverage_deg <= 230.0f, "a spike read as coverage");
        }
        if (k == 300u) { /* the garbage burst, 150 degrees into the turn */
            unsigned g;
            for (g = 0u; g < 8u; ++g) {
                magcal_vec3_t b;
                b.x = (float)(1200.0 * test_rand_uniform(&rng) - 600.0);
                b.y = (float)(1200.0 * test_rand_uniform(&rng) - 600.0);
                b.z = (float)(1200.0 * test_rand_uniform(&rng) - 600.0);
                push_ok(&g_st, &b);
            }
        }
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_progress(&g_st, &p));
        if ((k % 10u) == 0u && p.centre_source != MAGCAL_INTAKE_CENTRE_NONE && p.rebinning == 0u &&
            p.coverage_deg >= 200.0f) {
            magcal_status_t s;
            const float sc = solver_coverage(&g_st, &s);
            if (p.coverage_deg >= 270.0f) {
                started++;
                failed_cov += (s == MAGCAL_ERR_COVERAGE) ? 1u : 0u;
            }
            if (s == MAGCAL_OK || s == MAGCAL_ERR_UNOBSERVABLE || s == MAGCAL_ERR_COVERAGE) {
                const double d = fabs((double)p.coverage_deg - (double)sc);
                compared++;
                worst = (d > worst) ? d : worst;
                if (s == MAGCAL_OK) {
                    TEST_ASSERT_TRUE_MESSAGE(d <= 20.0 + 1e-3, "live coverage more than a sector per gap edge off");
                    adopted++;
                }
                within1 += (d <= 10.0 + 1e-3) ? 1u : 0u;
            }
        }
    }
    printf("progress vs solver: %u solves compared (%u OK), %u within one sector, largest difference %.0f deg; "
           "%u at >= 270 live, %u of them COVERAGE\n", compared, adopted, within1, worst, started, failed_cov);
    TEST_ASSERT_TRUE(adopted >= 10u);
    TEST_ASSERT_TRUE(started >= 10u);
}


/* Level band (intake.h, 2-D): raw z follows z = a + b cos + c sin of the direction (here a leak
 * of 1.2 uT amplitude of x, y into z); after two level circles around the installed centre a
 * sample pitched by 4 deg at north / south headings (z moved by H sin 4 = 1.4 uT, twice the band
 * of 0.03 x 20 uT) is refused REFUSED_LEVEL and counted, a level one in the same bin is stored;
 * at east / west headings the same pitch moves z by 0.1 uT only and is stored (documented);
 * band 0 stores the pitched ones. */
static magcal_vec3_t sample2_leak(double psi_deg, double pitch_deg, uint32_t *rng)
{
    magcal_vec3_t m = sample2(psi_deg, pitch_deg, 0.1, rng);
    m.z += (float)(0.05 * ((double)m.x - CX) - 0.03 * ((double)m.y - CY));
    return m;
}

static magcal_intake_outcome_t push_oc(magcal_intake_t *st, const magcal_vec3_t *m)
{
    magcal_intake_outcome_t oc = MAGCAL_INTAKE_STORED;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_push(st, m, &oc));
    return oc;
}

static void test_intake_level_band_refuses_pitched_samples(void)
{
    magcal_intake_cfg_t cfg = MAGCAL_INTAKE_CFG_DEFAULT_2D;
    const magcal_vec3_t c = {(float)CX, (float)CY, 0.0f};
    magcal_intake_counters_t c0;
    magcal_intake_counters_t c1;
    uint32_t rng = 4242u;
    unsigned pass;
    size_t k;
    unsigned refused_ns = 0u;
    unsigned level_ok = 0u;
    unsigned ew_stored = 0u;
    TEST_ASSERT_FLOAT_WITHIN(1e-6f, 0.0f, cfg.level_band_rel); /* off by default (opt-in) */
    cfg.level_band_rel = 0.6f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_intake_init(&g_st, &cfg, g_slots, 288u));
    cfg.level_band_rel = NAN;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_intake_init(&g_st, &cfg, g_slots, 288u));
    for (pass = 0u; pass < 2u; ++pass) {
        cfg.level_band_rel = pass == 0u ? 0.03f : 0.0f;
        init2(&g_st, g_slots, &cfg);
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_set_centre(&g_st, &c, (float)H));
        for (k = 0u; k < 2u * 24u * 50u; ++k) { /* two level circles, 15 deg/s at 50 Hz */
            magcal_vec3_t m = sample2_leak(15.0 * (double)k / 50.0, 0.0, &rng);
            push_ok(&g_st, &m);
        }
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_counters(&g_st, &c0));
        TEST_ASSERT_EQUAL_UINT32(0u, c0.refused_level);
        refused_ns = 0u;
        level_ok = 0u;
        ew_stored = 0u;
        for (k = 0u; k < 40u; ++k) {
            /* headings 3 .. 7 deg (north) and 183 .. 187 (south), spaced beyond the bins' spacing */
            const double psi = (k % 2u == 0u ? 3.0 : 183.0) + 0.1 * (double)(k / 2u);
            magcal_vec3_t up = sample2_leak(psi, 4.0, &rng);
            magcal_vec3_t lv = sample2_leak(psi + 0.05, 0.0, &rng);
            magcal_vec3_t ew = sample2_leak(psi + 87.0, 4.0, &rng);
            refused_ns += push_oc(&g_st, &up) == MAGCAL_INTAKE_REFUSED_LEVEL ? 1u : 0u;
            level_ok += push_oc(&g_st, &lv) != MAGCAL_INTAKE_REFUSED_LEVEL ? 1u : 0u;
            ew_stored += push_oc(&g_st, &ew) != MAGCAL_INTAKE_REFUSED_LEVEL ? 1u : 0u;
        }
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_counters(&g_st, &c1));
        printf("level band %.2f: pitched N/S refused %u of 40, level stored-or-spaced %u of 40, pitched E/W %u of 40 "
               "not refused\n", (double)cfg.level_band_rel, refused_ns, level_ok, ew_stored);
        TEST_ASSERT_EQUAL_UINT32(c1.refused_level - c0.refused_level, refused_ns);
        TEST_ASSERT_EQUAL_UINT(40u, level_ok);
        TEST_ASSERT_TRUE(ew_stored >= 36u);
        if (pass == 0u) {
            TEST_ASSERT_EQUAL_UINT(40u, refused_ns);
        } else {
            TEST_ASSERT_EQUAL_UINT(0u, refused_ns);
        }
    }
}

/* Level preference (intake.h, 2-D, magcal_intake_push_tilt): one 10-degree sector with cap 4
 * around the installed centre. A LEVEL sample entering the full bin replaces its oldest
 * non-level sample; a TILTED one then replaces only the remaining non-level ones (never a level
 * one); once the bin holds 4 level samples a TILTED one is refused (REFUSED_TILTED, counted) and
 * a LEVEL one replaces the oldest level one. Exact contents checked after each phase. */
static magcal_vec3_t sector_sample(unsigned i)
{
    const double a = (2.0 + 0.25 * (double)i) * D2R; /* raw angle atan2(-ux, uy), one sector */
    magcal_vec3_t m;
    m.x = (float)(CX - H * sin(a));
    m.y = (float)(CY + H * cos(a));
    m.z = (float)CZ;
    return m;
}

static unsigned store_holds(const magcal_vec3_t *seq, const unsigned *idx, unsigned n_idx)
{
    size_t n = 0u, k;
    unsigned i, found = 0u;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_snapshot3(&g_st, g_out, 16u, &n));
    TEST_ASSERT_EQUAL_UINT32(n_idx, (uint32_t)n);
    for (i = 0u; i < n_idx; ++i) {
        for (k = 0u; k < n; ++k) {
            found += (memcmp(&g_out[k], &seq[idx[i]], sizeof(seq[0])) == 0) ? 1u : 0u;
        }
    }
    return found;
}

static magcal_intake_outcome_t push_tilt_oc(magcal_intake_t *st, const magcal_vec3_t *m, magcal_intake_tilt_t t)
{
    magcal_intake_outcome_t oc = MAGCAL_INTAKE_STORED;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_push_tilt(st, m, t, &oc));
    return oc;
}

static void test_intake_push_tilt_level_samples_preferred_in_full_bin(void)
{
    magcal_intake_cfg_t cfg = MAGCAL_INTAKE_CFG_DEFAULT_2D;
    const magcal_vec3_t c = {(float)CX, (float)CY, (float)CZ};
    magcal_intake_counters_t ctr;
    magcal_vec3_t seq[16];
    unsigned i;
    static const unsigned after_level[4] = {2u, 3u, 4u, 5u};    /* tilted 2, 3 kept, level 4, 5 */
    static const unsigned after_tilted[4] = {4u, 5u, 7u, 8u};   /* level 4, 5 kept; tilted 7, 8 newest */
    static const unsigned all_level[4] = {4u, 5u, 9u, 10u};
    static const unsigned aged_level[4] = {5u, 9u, 10u, 12u};   /* level 12 replaced level 4 */
    for (i = 0u; i < 16u; ++i) {
        seq[i] = sector_sample(i);
    }
    cfg.per_bin = 4u;
    cfg.min_spacing_rel = 0.001f; /* 0.02 uT (0.04 in a full bin); the samples are 0.09 uT apart */
    cfg.tilt_limit_deg = 31.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_intake_init(&g_st, &cfg, g_slots, 144u));
    cfg.tilt_limit_deg = 2.0f;
    cfg.g_band_rel = 0.0f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_ERR_ARG, magcal_intake_init(&g_st, &cfg, g_slots, 144u));
    cfg.g_band_rel = 0.1f;
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_init(&g_st, &cfg, g_slots, 144u));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_set_centre(&g_st, &c, (float)H));
    for (i = 0u; i < 4u; ++i) { /* 0..3 tilted fill the bin */
        TEST_ASSERT_EQUAL_INT(MAGCAL_INTAKE_STORED, push_tilt_oc(&g_st, &seq[i], MAGCAL_INTAKE_TILT_TILTED));
    }
    TEST_ASSERT_EQUAL_INT(MAGCAL_INTAKE_REPLACED, push_tilt_oc(&g_st, &seq[4], MAGCAL_INTAKE_TILT_LEVEL));
    TEST_ASSERT_EQUAL_INT(MAGCAL_INTAKE_REPLACED, push_tilt_oc(&g_st, &seq[5], MAGCAL_INTAKE_TILT_LEVEL));
    TEST_ASSERT_EQUAL_UINT(4u, store_holds(seq, after_level, 4u)); /* the two oldest tilted went */
    for (i = 6u; i < 9u; ++i) { /* tilted 6, 7, 8: each over the oldest NON-level sample */
        TEST_ASSERT_EQUAL_INT(MAGCAL_INTAKE_REPLACED, push_tilt_oc(&g_st, &seq[i], MAGCAL_INTAKE_TILT_TILTED));
    }
    TEST_ASSERT_EQUAL_UINT(4u, store_holds(seq, after_tilted, 4u));
    TEST_ASSERT_EQUAL_INT(MAGCAL_INTAKE_REPLACED, push_tilt_oc(&g_st, &seq[9], MAGCAL_INTAKE_TILT_LEVEL));
    TEST_ASSERT_EQUAL_INT(MAGCAL_INTAKE_REPLACED, push_tilt_oc(&g_st, &seq[10], (magcal_intake_tilt_t)1));
    TEST_ASSERT_EQUAL_UINT(4u, store_holds(seq, all_level, 4u));
    /* full of level samples: a tilted or an unknown (magcal_intake_push) one is refused, counted */
    TEST_ASSERT_EQUAL_INT(MAGCAL_INTAKE_REFUSED_TILTED, push_tilt_oc(&g_st, &seq[11], MAGCAL_INTAKE_TILT_TILTED));
    TEST_ASSERT_EQUAL_INT(MAGCAL_INTAKE_REFUSED_TILTED, push_oc(&g_st, &seq[13]));
    TEST_ASSERT_EQUAL_INT(MAGCAL_INTAKE_REFUSED_TILTED,
                          push_tilt_oc(&g_st, &seq[14], (magcal_intake_tilt_t)7)); /* out of range: unknown */
    TEST_ASSERT_EQUAL_UINT(4u, store_holds(seq, all_level, 4u));
    /* the level samples still age among themselves: the newest level replaces the oldest level */
    TEST_ASSERT_EQUAL_INT(MAGCAL_INTAKE_REPLACED, push_tilt_oc(&g_st, &seq[12], MAGCAL_INTAKE_TILT_LEVEL));
    TEST_ASSERT_EQUAL_UINT(4u, store_holds(seq, aged_level, 4u));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_counters(&g_st, &ctr));
    TEST_ASSERT_EQUAL_UINT32(3u, ctr.refused_tilted);
    TEST_ASSERT_EQUAL_UINT32(5u, ctr.stored_level);
    TEST_ASSERT_EQUAL_UINT32(4u, ctr.added);
    TEST_ASSERT_EQUAL_UINT32(8u, ctr.replaced);
    TEST_ASSERT_EQUAL_UINT32(0u, ctr.refused_spacing);
}

/* Never starve (intake.h): a drive that is hilly throughout (every sample TILTED: pitch
 * +-5 deg, circles at 15 deg/s for 20 minutes at 50 Hz) builds exactly the store that the same
 * stream without tilt codes builds (magcal_intake_push), sample for sample and counter for
 * counter, and that store covers the circle; a 3-D store ignores the codes (LEVEL there changes
 * nothing either). */
static void test_intake_push_tilt_hilly_drive_never_starves(void)
{
    magcal_intake_cfg_t cfg = MAGCAL_INTAKE_CFG_DEFAULT_2D;
    magcal_intake_counters_t ca;
    magcal_intake_counters_t cb;
    magcal_intake_progress_t p;
    uint32_t rng = 77u;
    size_t k, na = 0u, nb = 0u;
    init2(&g_st, g_slots, &cfg);
    init2(&g_st_b, g_slots_b, &cfg);
    for (k = 0u; k < 20u * 60u * 50u; ++k) {
        const double t = (double)k / 50.0;
        const magcal_vec3_t m = sample2(15.0 * t, 5.0 * sin(2.0 * PI_D * t / 37.0), 0.1, &rng);
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_push_tilt(&g_st, &m, MAGCAL_INTAKE_TILT_TILTED, NULL));
        push_ok(&g_st_b, &m);
    }
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_counters(&g_st, &ca));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_counters(&g_st_b, &cb));
    TEST_ASSERT_EQUAL_MEMORY(&cb, &ca, sizeof ca);
    TEST_ASSERT_EQUAL_UINT32(0u, ca.refused_tilted);
    TEST_ASSERT_EQUAL_UINT32(0u, ca.stored_level);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_snapshot3(&g_st, g_out, 288u, &na));
    {
        static magcal_vec3_t out_b[288];
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_snapshot3(&g_st_b, out_b, 288u, &nb));
        TEST_ASSERT_EQUAL_UINT32((uint32_t)nb, (uint32_t)na);
        TEST_ASSERT_EQUAL_MEMORY(out_b, g_out, na * sizeof g_out[0]);
    }
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_progress(&g_st, &p));
    TEST_ASSERT_TRUE(na >= 280u); /* every bin (nearly) full: 36 x 8 = 288 slots */
    TEST_ASSERT_TRUE(p.coverage_deg >= 350.0f);
    {
        magcal_intake_cfg_t cfg3 = MAGCAL_INTAKE_CFG_DEFAULT_3D;
        const magcal_vec3_t m = {10.0f, 20.0f, 30.0f};
        magcal_intake_outcome_t oc = MAGCAL_INTAKE_REFUSED_SPACING;
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_init(&g_st, &cfg3, g_slots3,
                                                            sizeof g_slots3 / sizeof g_slots3[0]));
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_push_tilt(&g_st, &m, MAGCAL_INTAKE_TILT_LEVEL, &oc));
        TEST_ASSERT_EQUAL_INT(MAGCAL_INTAKE_STORED, oc);
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_counters(&g_st, &ca));
        TEST_ASSERT_EQUAL_UINT32(0u, ca.stored_level);
    }
}

/* A driver's garbage burst of more samples than the trim depth before the first turn (as the
 * 30-min gen_drive seed-4 drive, rows 7175..7213): 40 samples uniform in +-600 uT per axis, then
 * 1.5 turns of the ring (hard iron (30, -20), H = 20) at 15 deg/s, 50 Hz. The trimmed extremes
 * are garbage (reference radius hundreds of uT, its fit band misses the ring); the inner-cluster
 * reference (sweep.c) must give a provisional centre within 2 uT of the truth (the ring's centre
 * is (CX, CY) up to its soft-iron leak: within 0.5 uT), with the garbage still stored. */
static void test_intake_garbage_burst_does_not_own_the_reference(void)
{
    magcal_intake_cfg_t cfg = MAGCAL_INTAKE_CFG_DEFAULT_2D;
    magcal_intake_progress_t p;
    uint32_t rng = 4u;
    unsigned k;
    init2(&g_st, g_slots, &cfg);
    for (k = 0u; k < 40u; ++k) {
        magcal_vec3_t m;
        m.x = (float)(1200.0 * test_rand_uniform(&rng) - 600.0);
        m.y = (float)(1200.0 * test_rand_uniform(&rng) - 600.0);
        m.z = (float)(1200.0 * test_rand_uniform(&rng) - 600.0);
        push_ok(&g_st, &m);
    }
    drive_arc(&g_st, 10.0, 540.0, 15.0, 50.0, &rng);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_settle(&g_st));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_progress(&g_st, &p));
    printf("garbage burst: centre source %d, centre (%.2f, %.2f) R %.2f, coverage %.0f, stored %u\n",
           (int)p.centre_source, (double)p.centre.x, (double)p.centre.y, (double)p.radius, (double)p.coverage_deg,
           (unsigned)p.stored);
    TEST_ASSERT_EQUAL_INT(MAGCAL_INTAKE_CENTRE_PROVISIONAL, p.centre_source);
    TEST_ASSERT_TRUE(hypot((double)p.centre.x - CX, (double)p.centre.y - CY) <= 2.0);
    TEST_ASSERT_TRUE(fabs((double)p.radius - H) <= 0.1 * H);
    TEST_ASSERT_TRUE(p.coverage_deg >= 350.0f);
}

/* A provisional centre locked on a small circle (30-min gen_drive seed 10: a clump of the ring
 * fitted as a circle of r 1.9 for a ring of 21, kept for the whole drive): 3 turns on a circle
 * of r 2 uT around a point of the ring (3 deg/s), then 1.5 turns of the ring at 15 deg/s. With
 * ref_free (the continuous calibrator sets it before its first calibration) a ring fit whose tight
 * band holds under half the samples surveyed is dropped, the trimmed extremes give the next
 * reference, and the centre comes within 2 uT of the truth, R within 10 %. Without it (the
 * store's default) the small circle keeps the centre: measured (8.93, -20.59) R 2.00, coverage
 * 180; with it (29.88, -20.05) R 19.93, coverage 340. */
static void lock_drive(uint8_t ref_free, magcal_intake_progress_t *p)
{
    magcal_intake_cfg_t cfg = MAGCAL_INTAKE_CFG_DEFAULT_2D;
    uint32_t rng = 10u;
    const magcal_vec3_t q = sample2(90.0, 0.0, 0.0, &rng);
    unsigned k;
    init2(&g_st, g_slots, &cfg);
    g_st.ref_free = ref_free;
    for (k = 0u; k < 3u * 120u * 50u / 3u; ++k) {
        const double a = 3.0 * (double)k / 50.0 * D2R; /* 3 deg/s */
        magcal_vec3_t m = q;
        m.x += (float)(2.0 * cos(a) + 0.05 * test_rand_normal(&rng));
        m.y += (float)(2.0 * sin(a) + 0.05 * test_rand_normal(&rng));
        push_ok(&g_st, &m);
    }
    drive_arc(&g_st, 90.0, 540.0, 15.0, 50.0, &rng);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_settle(&g_st));
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_progress(&g_st, p));
    printf("small-circle lock, ref_free %u: centre source %d, centre (%.2f, %.2f) R %.2f, coverage %.0f\n",
           (unsigned)ref_free, (int)p->centre_source, (double)p->centre.x, (double)p->centre.y, (double)p->radius,
           (double)p->coverage_deg);
}

void test_intake_small_circle_lock_released(void)
{
    magcal_intake_progress_t p;
    lock_drive(0u, &p);
    TEST_ASSERT_TRUE((double)p.radius <= 0.5 * H); /* the scenario locks the default store */
    lock_drive(1u, &p);
    TEST_ASSERT_EQUAL_INT(MAGCAL_INTAKE_CENTRE_PROVISIONAL, p.centre_source);
    TEST_ASSERT_TRUE(hypot((double)p.centre.x - CX, (double)p.centre.y - CY) <= 2.0);
    TEST_ASSERT_TRUE(fabs((double)p.radius - H) <= 0.1 * H);
}

/* The cut of an INCONSISTENT solve (magcal_intake_drop_older, bin by bin as the continuous
 * calibrator's snapshot runs it): 36 samples on the ring (one per sector), then 36 newer ones 3 deg
 * on, every second of them at 1.6 R (off the ring by more than half its radius). A cut at the
 * first newer push keeps exactly the 18 newer samples on the ring, copies them in bin order (as
 * the snapshot), and the stored count follows; a cap shorter than that copies only the cap, the
 * store is compacted all the same; without a ring (radius 0) only the age cut applies. */
static unsigned cut_fill(void)
{
    const magcal_intake_cfg_t cfg = MAGCAL_INTAKE_CFG_DEFAULT_2D;
    const magcal_vec3_t c = {(float)CX, (float)CY, 0.0f};
    unsigned i;
    init2(&g_st, g_slots, &cfg);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_set_centre(&g_st, &c, (float)H));
    for (i = 0u; i < 72u; ++i) {
        const double psi = (5.0 + 10.0 * (double)(i % 36u) + (i >= 36u ? 3.0 : 0.0)) * D2R;
        const double d = (i >= 36u && (i % 2u) != 0u) ? 1.6 * H : H;
        magcal_intake_outcome_t oc;
        magcal_vec3_t m;
        m.x = (float)(CX - d * sin(psi));
        m.y = (float)(CY + d * cos(psi));
        m.z = (float)Z;
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_push(&g_st, &m, &oc));
        TEST_ASSERT_EQUAL_INT(MAGCAL_INTAKE_STORED, oc);
    }
    TEST_ASSERT_EQUAL_UINT32(72u, g_st.ctr.stored);
    return 37u; /* the push count of the first newer sample */
}

static uint32_t cut_all(uint32_t seq_limit, float ring_r, magcal_vec2_t *out, size_t cap)
{
    const magcal_vec2_t c = {(float)CX, (float)CY};
    uint32_t n = 0u;
    uint32_t b;
    for (b = 0u; b < g_st.n_bins; ++b) {
        magcal_intake_drop_older(&g_st, b, seq_limit, &c, ring_r, out, cap, &n);
    }
    return n;
}

void test_intake_drop_older_keeps_newer_samples_on_the_ring(void)
{
    static magcal_vec2_t out[80];
    static magcal_vec2_t snap[80];
    const uint32_t lim = cut_fill();
    size_t ns = 0u;
    uint32_t n;
    uint32_t i;
    n = cut_all(lim, (float)H, out, 80u);
    TEST_ASSERT_EQUAL_UINT32(18u, n);
    TEST_ASSERT_EQUAL_UINT32(18u, g_st.ctr.stored);
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_intake_snapshot2(&g_st, snap, 80u, &ns));
    TEST_ASSERT_EQUAL_UINT32(18u, (uint32_t)ns);
    for (i = 0u; i < n; ++i) {
        const double dx = (double)out[i].x - CX;
        const double dy = (double)out[i].y - CY;
        double a = atan2(-dx, dy) / D2R;
        a = a < 0.0 ? a + 360.0 : a;
        TEST_ASSERT_FLOAT_WITHIN(1e-3f, (float)H, (float)sqrt(dx * dx + dy * dy)); /* on the ring */
        TEST_ASSERT_FLOAT_WITHIN(1e-2f, 8.0f, (float)fmod(a, 10.0));               /* a newer sample (+3 deg) */
        TEST_ASSERT_EQUAL_FLOAT(snap[i].x, out[i].x); /* the store's own order (bin order) */
        TEST_ASSERT_EQUAL_FLOAT(snap[i].y, out[i].y);
    }
    /* a second cut at the same limit drops nothing more */
    TEST_ASSERT_EQUAL_UINT32(18u, cut_all(lim, (float)H, out, 80u));
    TEST_ASSERT_EQUAL_UINT32(18u, g_st.ctr.stored);
}

void test_intake_drop_older_short_cap_still_compacts(void)
{
    static magcal_vec2_t out[5];
    const uint32_t lim = cut_fill();
    TEST_ASSERT_EQUAL_UINT32(5u, cut_all(lim, (float)H, out, 5u));
    TEST_ASSERT_EQUAL_UINT32(18u, g_st.ctr.stored);
}

void test_intake_drop_older_without_ring_cuts_by_age_only(void)
{
    static magcal_vec2_t out[80];
    const uint32_t lim = cut_fill();
    TEST_ASSERT_EQUAL_UINT32(36u, cut_all(lim, 0.0f, out, 80u));
    TEST_ASSERT_EQUAL_UINT32(36u, g_st.ctr.stored);
    /* a limit before every push keeps everything */
    TEST_ASSERT_EQUAL_UINT32(36u, cut_all(1u, 0.0f, out, 80u));
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_intake_init_validates_config_and_storage);
    RUN_TEST(test_intake_bad_calls_return_status);
    RUN_TEST(test_intake_newest_replaces_oldest_in_its_bin);
    RUN_TEST(test_intake_saturated_samples_refused_and_counted);
    RUN_TEST(test_intake_spike_in_first_sample_does_not_move_centre);
    RUN_TEST(test_intake_parked_hour_fills_only_its_own_bin);
    RUN_TEST(test_intake_straight_hour_with_hills_fills_only_its_own_bins);
    RUN_TEST(test_intake_progress_agrees_with_posthoc_coverage);
    RUN_TEST(test_intake_rate_independent_defaults);
    RUN_TEST(test_intake_3d_tumble_coverage_mask);
    RUN_TEST(test_intake_installed_centre_rebins_store);
    RUN_TEST(test_intake_same_stream_same_store);
    RUN_TEST(test_intake_progress_coverage_agrees_with_solver_despite_spikes);
    RUN_TEST(test_intake_level_band_refuses_pitched_samples);
    RUN_TEST(test_intake_push_tilt_level_samples_preferred_in_full_bin);
    RUN_TEST(test_intake_push_tilt_hilly_drive_never_starves);
    RUN_TEST(test_intake_garbage_burst_does_not_own_the_reference);
    RUN_TEST(test_intake_small_circle_lock_released);
    RUN_TEST(test_intake_drop_older_keeps_newer_samples_on_the_ring);
    RUN_TEST(test_intake_drop_older_short_cap_still_compacts);
    RUN_TEST(test_intake_drop_older_without_ring_cuts_by_age_only);
    return UNITY_END();
}
