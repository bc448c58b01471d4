/**
 * @file continuous3.h
 * @brief Continuous 3-D calibrator (issue 13): the ellipsoid calibration a vehicle or a hand-held
 *        device runs from power-up for its whole life. Informative samples go into the 3-D intake
 *        store (intake.h: cells of an equal-area mask on the sphere, a cap per cell, newest
 *        replacing oldest); a solve is magcal_ellipsoid_calibrate() (ellipsoid.h: pre-test,
 *        density stage when needed, fit, trust gates) on a snapshot of the store; a candidate is
 *        adopted only when it is better than the installed calibration on the same samples
 *        (never-worse, with ageing); a persistent field-norm mismatch of new samples with the
 *        installed calibration is declared a change and relearned. docs/calibration_3d.md
 *        "Continuous 3-D" has the state diagram, the rules and the measured numbers.
 *
 * The design mirrors the 2-D loop (continuous.h). Per loop iteration the firmware calls:
 *  - magcal_cont3_push(): one raw sample and its time stamp (ms). O(1): it only writes into a
 *    MAGCAL_CONT3_RING-sample single-producer / single-consumer ring inside the instance.
 *  - magcal_cont3_step(): at most cfg.step_budget estimated Cortex-M4F instructions of work
 *    (default MAGCAL_SLICE_BUDGET_DEFAULT): the drain of the ring into the store, piece by piece
 *    (a sample's judge and store push, then its store sweep steps one at a time; one sample per
 *    step, a second only while the ring is a quarter full, at most cfg.drain_per_step; each
 *    sample judged against the installed calibration first: trust, change detection), and the
 *    next unit of solve work, every one resumable: (1) the coverage count that decides whether a
 *    solve is worth it, cell by cell, (2) the snapshot of the store into the solver buffer, cell by
 *    cell (the drain pauses for its one or two steps), (3) the solve,
 *    magcal_ellipsoid_calibrate_step with the budget but a reserve for the drain, (4) the adoption
 *    judgement (|B| spread of candidate and installed calibration on the snapshot), sample by
 *    sample. Returns MAGCAL_CONT3_IN_PROGRESS while a solve is under way. At the default budget no
 *    call exceeds 10,000 M4F instructions on the bench tumble (docs/calibration_3d.md "Work per
 *    call": the largest measured step, `m4f_max_call3_instr`; with glitch bursts and spikes, whose
 *    solves run the time-sliced density stage, `m4f_max_call3_dirty_instr`); the solver's
 *    indivisible visits (a 9x9 LDL^T solve: 7,500 estimated) are the largest pieces. In the density
 *    stage (its visits are small) the solver keeps for the drain only its next piece's cost.
 *  - magcal_cont3_heading(): heading of a raw sample with the installed calibration, tilt
 *    compensated when the caller passes gravity, its trust and the generation.
 *
 * States (no sticky state; every state returns to COLLECTING by itself):
 *  COLLECTING -> SOLVING   when the store has a centre, fills at least cfg.solve_fill of its
 *                          cells AND at least cfg.min_new x 2^min(f, 6) x (1 + min(r, 63))
 *                          samples were stored since the last solve (new information; f = failed
 *                          solves in a row, r = refusals in a row: a sensor at rest, or a store
 *                          that keeps confirming the installed calibration, does not solve again
 *                          and again), or, after a NOT_BETTER verdict, cfg.age_ms / 4 later (the
 *                          installed calibration has aged: a lower margin);
 *  SOLVING -> COLLECTING   when the solve ends (adopted, refused or failed: collection never
 *                          stops; pushes continue during the solve);
 *  any -> RELEARNING       when a change is declared (old samples dropped);
 *  RELEARNING -> SOLVING   as COLLECTING; a solve that adopts, or that finds the installed
 *                          calibration not worse on fresh data (NOT_BETTER), ends the relearning.
 *
 * Concurrency contract (as continuous.h). magcal_cont3_push() may run in an interrupt (or another
 * task) while ANY other call on the same instance runs in one task: the ring is the only state push
 * writes (its head index, after the sample; step only writes the tail index). Everything else
 * (step, solve_blocking, heading, progress, status) must run in ONE task context. Two push callers
 * on one instance need the caller's own lock. A full ring drops the sample and counts it
 * (MAGCAL_ERR_BUFFER_FULL). The index handover uses MAGCAL_CONT3_BARRIER(). Instances are
 * independent: one per magnetometer.
 *
 * Memory (caller-owned): store slots MAGCAL_CONT3_SLOTS(bands, per_bin), a solver buffer of as
 * many magcal_vec3_t, and a solver workspace of MAGCAL_CONT3_WORKSPACE_LEN(n_slots) bytes
 * (magcal_ellipsoid_calibrate's workspace for the snapshot; use the macro: it follows ellipsoid.h).
 *
 * @code
 * #include "magcal/continuous3.h"
 * #define SLOTS3 MAGCAL_CONT3_SLOTS(10u, 4u)
 * static magcal_intake_slot_t slots[SLOTS3];
 * static magcal_vec3_t solve_buf[SLOTS3];
 * static MAGCAL_CONT3_WORKSPACE_DECLARE(work, SLOTS3);
 * static magcal_cont3_t c3;
 * void init(const magcal_ellipsoid_cal_t *from_flash) {
 *     const magcal_cont3_cfg_t cfg = MAGCAL_CONT3_CFG_DEFAULT;
 *     (void)magcal_cont3_init(&c3, &cfg, from_flash, slots, SLOTS3, solve_buf, work, sizeof work);
 * }
 * void mag_isr(magcal_vec3_t m, uint32_t now_ms) { (void)magcal_cont3_push(&c3, &m, now_ms); }
 * void low_priority_task(magcal_vec3_t raw, magcal_vec3_t accel_g) {
 *     magcal_cont3_heading_t hd;
 *     if (magcal_cont3_step(&c3) == MAGCAL_CONT3_ADOPTED) { save_to_flash(&c3.cal); }
 *     if (magcal_cont3_heading(&c3, &raw, &accel_g, 0.0f, &hd) == MAGCAL_OK &&
 *         hd.trust == MAGCAL_TRUST_OK) {
 *         use(hd.heading_deg);
 *     }
 * }
 * @endcode
 */
#ifndef MAGCAL_CONTINUOUS3_H
#define MAGCAL_CONTINUOUS3_H

#include <stddef.h>
#include <stdint.h>

#include "magcal/config.h"
#include "magcal/ellipsoid.h"
#include "magcal/heading.h"
#include "magcal/intake.h"
#include "magcal/status.h"
#include "magcal/types.h"

#ifdef __cplusplus
extern "C" {
#endif

#ifndef MAGCAL_CONT3_RING
#define MAGCAL_CONT3_RING 32u /**< push ring: samples (power of two) */
#endif

#ifndef MAGCAL_CONT3_BARRIER
#if defined(__GNUC__) || defined(__clang__)
#define MAGCAL_CONT3_BARRIER() __atomic_thread_fence(__ATOMIC_SEQ_CST)
#else
#define MAGCAL_CONT3_BARRIER() ((void)0) /**< define it for your compiler (a full memory barrier) */
#endif
#endif

/** Change-detection cells of the corrected field direction: 6 cube faces x 4 quadrants. */
#define MAGCAL_CONT3_CELLS 24u

/** Store slots = solver buffer samples of a 3-D intake configuration (an upper bound). */
#define MAGCAL_CONT3_SLOTS(bands, per_bin) MAGCAL_INTAKE_SLOTS_3D(bands, per_bin)
/** Solver workspace bytes for a store of n_slots slots. */
#define MAGCAL_CONT3_WORKSPACE_LEN(n_slots) MAGCAL_ELLIPSOID_CALIBRATE_WORKSPACE_LEN(n_slots)
/** Declare `name` as an aligned solver workspace for n_slots slots. */
#define MAGCAL_CONT3_WORKSPACE_DECLARE(name, n_slots) MAGCAL_ELLIPSOID_CALIBRATE_WORKSPACE_DECLARE(name, n_slots)

/** Lifecycle state. */
typedef enum {
    MAGCAL_CONT3_COLLECTING = 0, /**< collecting; a solve starts when worth it */
    MAGCAL_CONT3_SOLVING = 1,    /**< a solve is under way (pushes continue) */
    MAGCAL_CONT3_RELEARNING = 2  /**< a change was declared: collecting fresh data */
} magcal_cont3_state_t;

/** Outcome of step(). */
typedef enum {
    MAGCAL_CONT3_IDLE = 0,        /**< collecting, no solve under way */
    MAGCAL_CONT3_IN_PROGRESS = 1, /**< a solve is under way: call step() again */
    MAGCAL_CONT3_ADOPTED = 2,     /**< a solve ended and installed a new calibration */
    MAGCAL_CONT3_REFUSED = 3,     /**< a solve passed the gates but the installed one was kept */
    MAGCAL_CONT3_FAILED = 4,      /**< the solve failed a gate (status: magcal_cont3_status) */
    MAGCAL_CONT3_CHANGE = 5       /**< a change was declared during this step's intake */
} magcal_cont3_outcome_t;

/** Configuration: start from MAGCAL_CONT3_CFG_DEFAULT. */
typedef struct {
    magcal_intake_cfg_t intake;              /**< store (3-D; default MAGCAL_CONT3_INTAKE_CFG_DEFAULT: 128 cells x 4) */
    magcal_ellipsoid_calibrate_cfg_t solver; /**< solve (default MAGCAL_ELLIPSOID_CALIBRATE_CFG_DEFAULT) */
    float solve_fill;         /**< filled share of the store's cells that starts a solve, (0, 1]
                                   (default 0.5: a ring of level turns fills ~0.2) */
    uint16_t min_samples;     /**< stored samples needed for a solve, >= 10 (default 60) */
    uint16_t min_new;         /**< samples stored since the last solve to start one, >= 1 (default 16) */
    uint16_t drain_per_step;  /**< ring samples moved into the store per step at most, >= 1 (default 2):
                                   the first always, more only while the ring is a quarter full and
                                   the budget holds them (catch-up after the steps that do not drain) */
    float adopt_margin;       /**< never-worse: the candidate's |B| spread x margin(t) must be below the
                                   installed calibration's on the same samples; >= 1 (default 1.02) */
    float age_ms;             /**< ageing: margin(t) = 1 + (adopt_margin - 1) / (1 + t / age_ms),
                                   t = ms of push stamps since the installed calibration was adopted
                                   (default 600000); never below 1 + 12 / n (n snapshot samples: a
                                   9-parameter fit's in-sample advantage over the truth, c3_adopt.c) */
    float mismatch_k;         /**< sample mismatch: | |h| / F - 1 | > max(k sigma, min) (default 4) */
    float mismatch_min_rel;   /**< floor of that threshold (default 0.05) */
    uint32_t change_ms;       /**< mismatch time of an open episode to declare a change (default 8000) */
    uint16_t change_cells;    /**< distinct direction cells (of MAGCAL_CONT3_CELLS) it must span (default 3) */
    uint32_t clear_ms;        /**< consistent time that closes an episode (default 4000) */
    uint32_t step_budget;     /**< work of the solve per step(), estimated Cortex-M4F instructions, >= 1
                                   (default MAGCAL_SLICE_BUDGET_DEFAULT; the solve is time-sliced:
                                   magcal_ellipsoid_calibrate_step; its density stage, when the pre-test
                                   runs it, is one step of its own) */
} magcal_cont3_cfg_t;

/** The store of MAGCAL_CONT3_CFG_DEFAULT: MAGCAL_INTAKE_CFG_DEFAULT_3D (10 bands = 128 cells x 4)
 *  with a minimum spacing of 1 % of R instead of 4 %: a hand tumble of a few hundred samples is
 *  then stored nearly whole (docs/calibration_3d.md "Continuous 3-D": the spacing only thins
 *  repeats; the cap per cell still bounds a parked sensor to its own cell). */
#define MAGCAL_CONT3_INTAKE_CFG_DEFAULT {3u, 4u, 10u, 8u, 0.01f, 0.05f, 0.0f, 0.0f, 0.0f, 0.1f}

/** Defaults: work untuned from 10 to 100 Hz (time constants are in ms of the push stamps). */
#define MAGCAL_CONT3_CFG_DEFAULT                                                                   \
    {                                                                                              \
        MAGCAL_CONT3_INTAKE_CFG_DEFAULT, MAGCAL_ELLIPSOID_CALIBRATE_CFG_DEFAULT, 0.5f, 60u, 16u, 2u, \
            1.02f, 600000.0f, 4.0f, 0.05f, 8000u, 3u, 4000u, MAGCAL_SLICE_BUDGET_DEFAULT           \
    }

/** A heading with its trust. */
typedef struct {
    float heading_deg;      /**< [0, 360): calibrated (raw when uncalibrated); tilt compensated when
                                 gravity was given, else atan2(-h.x, h.y) of the corrected field
                                 (valid only while the body is level: x right, y forward, z up) */
    float raw_heading_deg;  /**< the same formula on the raw sample (NaN when a calibration is installed
                                 and the raw field has no horizontal part) */
    float field_rel;        /**< |h| / F - 1 under the installed calibration (NaN if none) */
    float inclination_deg;  /**< with gravity: inclination of the corrected field, down positive
                                 (reported, not judged: the store has no gravity); else NaN */
    magcal_trust_state_t trust; /**< heading.h trust state */
    uint32_t generation;    /**< adoptions so far (0 = none) */
} magcal_cont3_heading_t;

/** Live progress. */
typedef struct {
    magcal_cont3_state_t state; /**< lifecycle */
    uint16_t cells;             /**< cells of the store's mask */
    uint16_t cells_filled;      /**< cells holding a sample */
    float fill;                 /**< cells_filled / cells (0 until the store has a centre) */
    float completion_pct;       /**< store completion (intake.h) */
    uint32_t mask[MAGCAL_INTAKE_MASK_WORDS(MAGCAL_INTAKE_MAX_BINS)]; /**< filled-cell mask (intake.h layout) */
    uint32_t stored;            /**< samples in the store */
    uint32_t new_since_solve;   /**< samples stored since the last solve */
    uint32_t generation;        /**< adoptions so far */
    uint32_t solves;            /**< solves finished */
    uint32_t changes;           /**< changes declared */
    uint32_t dropped;           /**< ring overflows */
    uint8_t episode_open;       /**< 1 while a mismatch episode is open */
} magcal_cont3_progress_t;

/** Instance (allocate statically). Fields private except `cal`, `last`, `cand_spread` and
 *  `inst_spread` (read-only). */
typedef struct {
    magcal_cont3_cfg_t cfg;
    uint32_t magic;
    magcal_intake_t store;
    magcal_vec3_t *buf;
    size_t slots;
    void *work;
    size_t work_len;
    size_t snap_n;                  /* samples in the solver buffer */
    magcal_ellipsoid_cal_t cal;     /**< read-only: installed calibration (valid when generation > 0 or from flash) */
    magcal_ellipsoid_result_t last; /**< read-only: fit of the last solve that returned MAGCAL_OK */
    float cand_spread;              /**< read-only: |B| spread (std / mean) of the last candidate on its snapshot */
    float inst_spread;              /**< read-only: the installed calibration's on the same snapshot (NaN: none) */
    float cal_sigma_rel;            /* installed: residual_rms / F (0: unknown, the floor applies) */
    uint8_t has_cal;
    uint8_t state;
    uint8_t stage;                  /* next solve unit: 0 none, 1 snapshot, 2 solve, 3 adopt */
    uint8_t change_flag;
    magcal_cont3_outcome_t last_outcome;
    magcal_status_t last_status;
    magcal_status_t solve_status;   /* status of the solve between stages 2 and 3 */
    uint32_t generation;
    uint32_t solves;
    uint32_t changes;
    uint32_t aged_adopts;           /* adoptions that needed the aged margin */
    uint8_t fail_run;               /* failed solves in a row (back-off, c3_step.c) */
    uint8_t refuse_run;             /* refusals in a row since the last adoption (back-off) */
    uint32_t stored_at_solve;
    uint32_t age_ms_acc;
    uint32_t solve_ms_acc;
    magcal_ellipsoid_result_t cand; /* candidate between stages 2 and 3 */
    magcal_ellipsoid_calibrate_slice_t slice; /* the solve under way (stage 2) */
    /* ring (push writes ring[head % N] then head; step reads then writes tail) */
    magcal_vec3_t ring[MAGCAL_CONT3_RING];
    uint32_t ring_t[MAGCAL_CONT3_RING];
    volatile uint32_t head;
    volatile uint32_t tail;
    volatile uint32_t dropped;
    /* change detection */
    uint32_t last_t;
    uint8_t have_t;
    uint8_t episode_open;
    uint32_t mis_ms;
    uint32_t clean_ms;
    uint32_t mis_cells;             /* MAGCAL_CONT3_CELLS bits of the open episode */
    /* time-sliced units (c3_step.c, c3_adopt.c): the state a unit resumes from */
    uint32_t left_;                 /* estimated M4F instructions left of this step's budget */
    uint32_t worth_key;             /* store counters at the last coverage count (none while unchanged) */
    uint8_t worth_checked;          /* 1: worth_key is valid */
    uint16_t sweep_left;            /* sweep steps the last stored sample still owes the store (c3_step.c) */
    uint8_t adopt_pass;             /* adoption: 0 entry, 1 candidate's spread, 2 installed's spread */
    uint16_t scan_bin;              /* coverage count / snapshot: next bin */
    uint16_t scan_filled;           /* coverage count: cells found filled so far */
    uint32_t adopt_k;               /* adoption: next snapshot sample of the pass */
    float ad_s1;                    /* adoption: the pass's sums (c3_adopt.c magcal_c3_spread) */
    float ad_s2;
    float ad_n;
    uint32_t sel[MAGCAL_MAX_SAMPLES / 32u]; /* adoption: snapshot samples on the candidate's shell */
} magcal_cont3_t;

#if MAGCAL_CFG_ENABLE_3D /* config.h feature switch: with 3-D off these functions are not built */

/**
 * @brief Initialise on caller storage.
 * @param[out] cc        instance.
 * @param[in]  cfg       configuration (copied); cfg->intake.dims must be 3 and its cells x
 *                       per_bin at most MAGCAL_MAX_SAMPLES (the solve's density-stage limit).
 * @param[in]  installed optional (NULL): 3-D calibration restored from flash (finite, F > 0,
 *                       det G > 0; its centre then indexes the store; generation stays 0).
 * @param[in]  slots     store slots, n_slots >= cells x per_bin (MAGCAL_CONT3_SLOTS), <= 65535.
 * @param[in]  n_slots   their number.
 * @param[in]  buf       solver buffer of n_slots samples.
 * @param[in]  work      solver workspace, 4-aligned, >= MAGCAL_CONT3_WORKSPACE_LEN(n_slots).
 * @param[in]  work_len  its bytes.
 * @return MAGCAL_OK, MAGCAL_ERR_NULL, MAGCAL_ERR_ARG (a cfg value out of range, dims != 3, a
 *         store larger than MAGCAL_MAX_SAMPLES, or `installed` not a calibration), MAGCAL_ERR_NONFINITE (cfg or installed),
 *         MAGCAL_ERR_WORKSPACE (n_slots or work_len too small), MAGCAL_ERR_ALIGNMENT.
 */
magcal_status_t magcal_cont3_init(magcal_cont3_t *cc, const magcal_cont3_cfg_t *cfg,
                                  const magcal_ellipsoid_cal_t *installed, magcal_intake_slot_t *slots,
                                  size_t n_slots, magcal_vec3_t *buf, void *work, size_t work_len);

/**
 * @brief Offer one raw sample (x right, y forward, z up; sensor unit) with its time in ms
 *        (wrapping uint32 allowed). ISR-safe (file comment). O(1).
 * @return MAGCAL_OK (queued), MAGCAL_ERR_BUFFER_FULL (ring full: dropped, counted),
 *         MAGCAL_ERR_NULL, MAGCAL_ERR_NOT_INITIALISED.
 */
magcal_status_t magcal_cont3_push(magcal_cont3_t *cc, const magcal_vec3_t *m, uint32_t t_ms);

/** @brief One unit of work (file comment); MAGCAL_CONT3_IDLE for NULL / uninitialised. */
magcal_cont3_outcome_t magcal_cont3_step(magcal_cont3_t *cc);

/**
 * @brief Host / test convenience: drain the ring, then, if a solve is worth running (or force),
 *        run it to its end. @return the final outcome (MAGCAL_CONT3_IDLE when no solve ran).
 */
magcal_cont3_outcome_t magcal_cont3_solve_blocking(magcal_cont3_t *cc, int force);

/**
 * @brief Heading of a raw sample with the installed calibration and its trust (the judge of
 *        step(), no state change). Task context.
 * @param[in]  cc              instance.
 * @param[in]  m               raw sample, body axes.
 * @param[in]  accel_g         specific force in g, body axes (tilt.h), or NULL: the heading then
 *                             assumes the body is level (atan2(-h.x, h.y)).
 * @param[in]  declination_deg east positive, [-180, 180].
 * @param[out] out             result; untouched on failure.
 * @return MAGCAL_OK, MAGCAL_ERR_NULL, MAGCAL_ERR_NOT_INITIALISED, MAGCAL_ERR_NONFINITE,
 *         MAGCAL_ERR_ARG (|declination| > 180), MAGCAL_ERR_ZERO_FIELD (no horizontal field), and
 *         with accel_g every status of magcal_tilt_heading() (FREE_FALL, ACCEL_NORM, GIMBAL).
 */
magcal_status_t magcal_cont3_heading(const magcal_cont3_t *cc, const magcal_vec3_t *m,
                                     const magcal_vec3_t *accel_g, float declination_deg,
                                     magcal_cont3_heading_t *out);

/** @brief Live progress. @return MAGCAL_OK, MAGCAL_ERR_NULL, MAGCAL_ERR_NOT_INITIALISED. */
magcal_status_t magcal_cont3_progress(const magcal_cont3_t *cc, magcal_cont3_progress_t *out);

/** @brief Status of the last finished solve (MAGCAL_OK before any; MAGCAL_ERR_NOT_BETTER when the
 *         installed calibration was kept). MAGCAL_ERR_NOT_INITIALISED for NULL / uninitialised. */
magcal_status_t magcal_cont3_status(const magcal_cont3_t *cc);

#endif /* MAGCAL_CFG_ENABLE_3D */

#ifdef __cplusplus
}
#endif

#endif /* MAGCAL_CONTINUOUS3_H */
