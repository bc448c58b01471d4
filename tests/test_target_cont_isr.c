/*
 * Interrupt / task interleaving of the continuous calibrator (continuous.h concurrency contract)
 * with a REAL asynchronous producer: on the QEMU target (preset cortex-m4f-tests) the SysTick
 * exception pushes the samples while the task steps, reads headings and progress; on the host a
 * SIGALRM handler (setitimer) does the same. The producer is what a firmware ISR is: one
 * magcal_cont_push_imu() (two thirds of the samples, with the gyro's rate) or magcal_cont_push()
 * of a precomputed sample per tick, retried on the next tick when the ring is full. Checked against the truth: every sample is taken by step exactly once or counted as
 * dropped, every OK heading the task read during the run is in [0, 360) with a generation that
 * never goes down, and the calibration adopted from the interleaved stream is accurate (heading
 * RMS over 72 true headings < 1 degree, the bar of tests/test_continuous.c).
 */
#if !defined(__arm__)
#define _POSIX_C_SOURCE 200809L
#include <signal.h>
#include <sys/time.h>
#endif
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "magcal/continuous.h"
#include "test_util.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

#define SLOTS MAGCAL_CONT_SLOTS(36u, 8u)
#define RATE_MS 20u      /* stamps of a 50 Hz sensor */
#define N_SAMPLES 3000u  /* 0.3 deg per sample: 900 deg of turning */

static magcal_intake_slot_t g_slots[SLOTS];
static magcal_vec2_t g_buf[SLOTS];
static MAGCAL_CALIBRATOR_WORKSPACE_DECLARE(g_work, SLOTS);
static magcal_cont_t g_cc;
static magcal_vec3_t g_samples[N_SAMPLES];

static const test_distortion_t k_d = {30.0f, {{1.10f, 0.05f}, {0.05f, 0.90f}}, 12.0f, -7.0f};

/* producer state: written only by the interrupt / signal handler while it runs */
static volatile uint32_t g_next;
static volatile uint32_t g_ok;
static volatile uint32_t g_full;
static volatile uint32_t g_ticks;

static void producer_tick(void)
{
    uint32_t i = g_next;
    g_ticks = g_ticks + 1u;
    if (i >= N_SAMPLES) {
        return;
    }
    /* the first two thirds with the gyro's rate of their 0.3 deg per sample (push_imu), the rest
     * through push: both producers' state is the interrupt's */
    static const magcal_vec3_t w = {0.0f, 0.0f, -0.3f / (RATE_MS * 1e-3f) * (3.14159265f / 180.0f)};
    magcal_status_t st;
    if (i < 2u * N_SAMPLES / 3u) {
        st = magcal_cont_push_imu(&g_cc, &g_samples[i], NULL, &w, i * RATE_MS);
    } else {
        st = magcal_cont_push(&g_cc, &g_samples[i], i * RATE_MS);
    }
    if (st == MAGCAL_OK) {
        g_ok = g_ok + 1u;
        g_next = i + 1u;
    } else {
        g_full = g_full + 1u; /* ring full: the same sample again on the next tick */
    }
}

#if defined(__arm__)
/* SysTick through a vector table in RAM (VTOR): the start-up table routes SysTick to the fault
 * handler, since the other tests never enable an interrupt. Without -icount, QEMU's SysTick runs
 * at 25 MHz of host time: a reload of 2500 ticks is a 10 kHz "sensor interrupt", about every
 * 10k guest instructions, so the ring fills during the solve stages (millions of instructions). */
#define SYST_CSR (*(volatile uint32_t *)0xE000E010u)
#define SYST_RVR (*(volatile uint32_t *)0xE000E014u)
#define SYST_CVR (*(volatile uint32_t *)0xE000E018u)
#define SCB_VTOR (*(volatile uint32_t *)0xE000ED08u)
typedef void (*vector_t)(void);
static vector_t g_vtab[16] __attribute__((aligned(128)));
static uint32_t g_vtor_saved;

void test_systick_isr(void);
void test_systick_isr(void)
{
    producer_tick();
}

static void producer_start(void)
{
    const vector_t *old = (const vector_t *)(uintptr_t)SCB_VTOR;
    unsigned k;
    for (k = 0u; k < 16u; ++k) {
        g_vtab[k] = old[k];
    }
    g_vtab[15] = test_systick_isr;
    g_vtor_saved = SCB_VTOR;
    SCB_VTOR = (uint32_t)(uintptr_t)g_vtab;
    __asm__ volatile("dsb\n isb" ::: "memory");
    SYST_RVR = 2499u;
    SYST_CVR = 0u;
    SYST_CSR = 7u; /* enable, interrupt, processor clock */
}

static void producer_stop(void)
{
    SYST_CSR = 0u;
    __asm__ volatile("dsb\n isb" ::: "memory");
    SCB_VTOR = g_vtor_saved;
}
#else
static void on_alarm(int sig)
{
    (void)sig;
    producer_tick();
}

static void producer_start(void)
{
    struct sigaction sa;
    struct itimerval it;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_alarm;
    sigemptyset(&sa.sa_mask);
    sa.sa_flags = SA_RESTART;
    TEST_ASSERT_EQUAL_INT(0, sigaction(SIGALRM, &sa, NULL));
    it.it_interval.tv_sec = 0;
    it.it_interval.tv_usec = 100; /* 10 kHz */
    it.it_value = it.it_interval;
    TEST_ASSERT_EQUAL_INT(0, setitimer(ITIMER_REAL, &it, NULL));
}

static void producer_stop(void)
{
    struct itimerval it;
    memset(&it, 0, sizeof it);
    (void)setitimer(ITIMER_REAL, &it, NULL);
    (void)signal(SIGALRM, SIG_IGN);
}
#endif

/* truth heading RMS of calibration c (72 noiseless headings), degrees */
static double truth_rms(const magcal_cal2d_t *c)
{
    double ss = 0.0;
    int k;
    uint32_t rng = 1u;
    for (k = 0; k < 72; ++k) {
        double psi = 5.0 * k;
        magcal_vec2_t p = test_distorted_sample(&k_d, psi, 0.0, &rng);
        float mag = 0.0f, tru = 0.0f;
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_heading_compute(c, p, 0.0f, &mag, &tru));
        ss += test_angle_diff_deg(mag, psi) * test_angle_diff_deg(mag, psi);
    }
    return sqrt(ss / 72.0);
}

static void test_cont_interrupt_push_interleaved_with_task_steps(void)
{
    const magcal_cont_cfg_t cfg = MAGCAL_CONT_CFG_DEFAULT;
    magcal_cont_progress_t p;
    magcal_cont_heading_t hd;
    const magcal_vec3_t probe = {12.0f, 23.0f, 40.0f};
    uint32_t rng = 99u, i, steps = 0u, gen = 0u, headings_ok = 0u, in_progress = 0u, tail_steps = 0u;
    for (i = 0u; i < N_SAMPLES; ++i) {
        magcal_vec2_t s = test_distorted_sample(&k_d, fmod(0.3 * (double)i, 360.0), 0.15, &rng);
        g_samples[i].x = s.x;
        g_samples[i].y = s.y;
        g_samples[i].z = 40.0f;
    }
    TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_init(&g_cc, &cfg, NULL, g_slots, SLOTS, g_buf, g_work,
                                                      sizeof g_work));
    g_next = 0u;
    g_ok = 0u;
    g_full = 0u;
    g_ticks = 0u;
    producer_start();
    while (g_next < N_SAMPLES || g_cc.tail != g_cc.head) {
        magcal_cont_outcome_t o = magcal_cont_step(&g_cc);
        in_progress += o == MAGCAL_CONT_IN_PROGRESS ? 1u : 0u;
        if (magcal_cont_heading(&g_cc, &probe, 0.0f, &hd) == MAGCAL_OK) {
            TEST_ASSERT_TRUE(hd.heading_deg >= 0.0f && hd.heading_deg < 360.0f);
            TEST_ASSERT_TRUE(hd.generation >= gen);
            gen = hd.generation;
            headings_ok++;
        }
        TEST_ASSERT_EQUAL_INT(MAGCAL_OK, magcal_cont_progress(&g_cc, &p));
        TEST_ASSERT_TRUE(p.coverage_deg >= 0.0f && p.coverage_deg <= 360.0f);
        steps++;
        TEST_ASSERT_TRUE(steps < 20000000u);
    }
    producer_stop();
    while (magcal_cont_step(&g_cc) == MAGCAL_CONT_IN_PROGRESS) {
        tail_steps++; /* a solve still under way when the last sample was taken */
    }
    printf("interleaved: %lu producer ticks, %lu pushes OK, %lu ring-full retries, %lu task steps "
           "(%lu in a solve; %lu after the last sample), generation %lu\n",
           (unsigned long)g_ticks, (unsigned long)g_ok, (unsigned long)g_full, (unsigned long)steps,
           (unsigned long)in_progress, (unsigned long)tail_steps, (unsigned long)g_cc.generation);
    TEST_ASSERT_EQUAL_UINT32(N_SAMPLES, g_ok);
    TEST_ASSERT_EQUAL_UINT32(N_SAMPLES, g_cc.tail); /* every queued sample taken exactly once */
    TEST_ASSERT_EQUAL_UINT32(g_full, g_cc.dropped);  /* every refusal counted */
    TEST_ASSERT_TRUE(in_progress > 0u);              /* solves ran while the producer pushed */
    TEST_ASSERT_EQUAL_UINT32(steps, headings_ok);
    TEST_ASSERT_TRUE(g_cc.generation >= 1u);
    TEST_ASSERT_TRUE(truth_rms(&g_cc.cal) < 1.0);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_cont_interrupt_push_interleaved_with_task_steps);
    return UNITY_END();
}
