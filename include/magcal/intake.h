/**
 * @file intake.h
 * @brief Informative sample store: the intake stage of the continuous calibrator (2-D and 3-D).
 *
 * Every raw sample is offered once (push, per sample, ISR or task). Only informative ones are kept:
 * - binned by direction around a centre: 2-D heading sectors of the (x, y) components, 3-D cells of
 *   an equal-area "igloo" mask on the sphere (latitude bands of equal height, each split into
 *   round(2 bands sin(colatitude)) cells: 6 bands = 46 cells, 8 = 82, 10 = 128, 12 = 184, 18 = 412);
 * - a cap per bin (cfg.per_bin): when a bin is full, the newest sample replaces its oldest, so the
 *   store ages and follows the current installation;
 * - a minimum spacing: a sample closer than cfg.min_spacing_rel x R (R: the radius of the field
 *   around the centre; twice that when the bin is full) to a sample already in its bin is refused
 *   (a parked or straight-driving vehicle repeats one direction: it fills at most its own bins,
 *   and its noise does not churn a full bin);
 * - samples at the declared range limit are refused (cfg.range_limit: a saturated axis is a fault,
 *   not data) with MAGCAL_ERR_SATURATED, and counted;
 * - 2-D level band (cfg.level_band_rel): a car on a hill shifts its forward axis by B_z sin(pitch),
 *   which an ellipse fit takes for centre and shape; the pitch also moves raw z (by about
 *   |h_forward| sin(pitch)). A bounded survey (one bin per push) fits the store's level model,
 *   z = a + b cos(phi) + c sin(phi) over the bins' median z (phi: the bin's direction from the
 *   centre; the b, c terms carry the soft-iron leak of x, y into z), and a sample more than
 *   level_band_rel x R from it is refused once its bin holds half its cap (REFUSED_LEVEL,
 *   counted). The first half of every bin is always taken, so a drive that is hilly throughout
 *   still fills its bins (with pitched samples: the band then only prefers the level ones that
 *   come later); pitch while heading magnetic east or west moves z only at second order and is
 *   not seen (docs/calibrator.md "2-D level band").
 * - 2-D level preference (magcal_intake_push_tilt: each sample with a tilt code, from the
 *   accelerometer, magcal_cont_push_g): a LEVEL sample entering a full bin replaces the bin's
 *   oldest non-level sample first (the oldest level one only when the bin holds no other); a
 *   non-level sample (TILTED or UNKNOWN) never replaces a level one: it is refused
 *   (REFUSED_TILTED, counted) once its bin holds cfg.per_bin level samples, and otherwise is
 *   stored as today (a free slot, or over the bin's oldest non-level sample). A drive that is
 *   hilly throughout (no level sample ever) therefore fills and ages every bin exactly as without
 *   gravity, and a store without tilt codes (magcal_intake_push: UNKNOWN) behaves exactly as
 *   before (docs/calibrator.md "Level samples from the accelerometer").
 *
 * The centre is the installed calibration's (magcal_intake_set_centre) when there is one, otherwise
 * a provisional one that one spike cannot move (never a bounding-box midpoint). A bounded sweep
 * (cfg.sweep_steps slots per push) surveys the store; at the end of each sweep (src/intake/sweep.c):
 * - a reference from TRIMMED extremes: per axis the t-th largest and t-th smallest stored value,
 *   t = min(8, 2 + stored / 16): fewer than t outliers on one side of an axis do not move it;
 * - a circle (2-D) or sphere (3-D) fit of the stored samples within [0.3, 3] x the reference
 *   radius of the reference (a spike never enters it), in 2-D refined to the centre of a conic fit
 *   once about 200 degrees are seen (soft iron); it becomes the centre only when the samples form
 *   a ring: non-degenerate scatter (about 70 degrees of arc or more), radial RMS <= 0.2 R. A parked
 *   or straight-driving vehicle never qualifies. Until the first usable fit the bins are around the
 *   raw origin (centre_source NONE); a bin that fills then keeps its spread (the nearest sample is
 *   replaced) instead of its newest.
 * A new centre more than cfg.recentre_rel x R from the old one re-bins the store over the next
 * sweeps (a moved sample keeps its age; moving into a full bin drops that bin's oldest).
 *
 * Progress (magcal_intake_progress) uses the calibrator's coverage definition: covered degrees =
 * (sectors - longest empty circular run) x sector width, the missing sector = that run; a solve
 * around its fitted centre finds the same within one sector when the centre is right. 3-D: filled
 * cells, a mask (magcal_intake_mask). Completion = share of bins holding at least ceil(per_bin / 2)
 * samples, each bin counted up to that depth. Once the store has a centre and a radius R, a bin
 * counts (coverage, completion, mask) only its samples ON THE RING, at [0.7, 1.4] x R from the
 * centre: a spike stays stored until its bin fills but is not coverage (the solver's filter
 * rejects it), and a provisional centre far from the ring's reads as little coverage.
 *
 * Memory: caller-owned slots, MAGCAL_INTAKE_SLOTS_2D(sectors, per_bin) or
 * MAGCAL_INTAKE_SLOTS_3D(bands, per_bin) of them; the instance holds the per-bin counts
 * (MAGCAL_INTAKE_MAX_BINS). Work per push: one atan2f (3-D: plus one sqrtf and a band search),
 * at most 2 x per_bin distance tests, and cfg.sweep_steps survey / re-bin steps (each at most one
 * atan2f and one insertion). No time constants: the defaults work from 10 to 100 Hz.
 *
 * Concurrency: one instance is not reentrant. push may run in an interrupt only if the task's
 * calls on the same instance (snapshot, progress, mask, set_centre, reset) are not interrupted by
 * it (mask the interrupt around them, or run everything in one context).
 */
#ifndef MAGCAL_INTAKE_H
#define MAGCAL_INTAKE_H

#include <stddef.h>
#include <stdint.h>

#include "magcal/status.h"
#include "magcal/types.h"

#ifdef __cplusplus
extern "C" {
#endif

#ifndef MAGCAL_INTAKE_MAX_BINS
#define MAGCAL_INTAKE_MAX_BINS 480u /**< most bins (2-D sectors or 3-D cells) of one store */
#endif
#define MAGCAL_INTAKE_MAX_BANDS 18u    /**< most 3-D latitude bands (410 cells) */
#define MAGCAL_INTAKE_MAX_PER_BIN 64u  /**< largest cap per bin */
#define MAGCAL_INTAKE_TRIM 8u          /**< deepest trimmed extreme of the provisional reference */

/** Upper bound of the cells of a 3-D mask of `bands` bands (exact count: magcal_intake_bins). */
#define MAGCAL_INTAKE_CELLS_3D_MAX(bands) ((4u * (bands) * (bands)) / 3u + (bands))
/** Slots a 2-D store needs. */
#define MAGCAL_INTAKE_SLOTS_2D(sectors, per_bin) ((size_t)(sectors) * (size_t)(per_bin))
/** Slots a 3-D store needs (an upper bound; init accepts any length >= cells x per_bin). */
#define MAGCAL_INTAKE_SLOTS_3D(bands, per_bin) ((size_t)MAGCAL_INTAKE_CELLS_3D_MAX(bands) * (size_t)(per_bin))
/** 32-bit words of a bin mask of `bins` bins. */
#define MAGCAL_INTAKE_MASK_WORDS(bins) (((size_t)(bins) + 31u) / 32u)

/** One stored sample (caller storage). Fields private. */
typedef struct {
    magcal_vec3_t m; /**< private: raw sample */
    uint32_t seq;    /**< private: push count when stored, 31 bits (age order, modulo 2^31 pushes);
                          bit 31: the sample is LEVEL (magcal_intake_push_tilt) */
} magcal_intake_slot_t;

/** Configuration. Start from MAGCAL_INTAKE_CFG_DEFAULT_2D or _3D. */
typedef struct {
    uint8_t dims;          /**< 2 (heading sectors of x, y) or 3 (cells on the sphere) */
    uint8_t per_bin;       /**< cap per bin, 1..MAGCAL_INTAKE_MAX_PER_BIN (2-D default 8, 3-D 4) */
    uint16_t bins;         /**< 2-D: sectors, 8..MAGCAL_INTAKE_MAX_BINS (default 36: 10 deg, the
                                calibrator's coverage bins); 3-D: latitude bands,
                                4..MAGCAL_INTAKE_MAX_BANDS (default 10: 128 cells) */
    uint16_t sweep_steps;  /**< survey / re-bin slots visited per push, >= 1 (default 8) */
    float min_spacing_rel; /**< minimum distance between samples of one bin / R, 0..0.5
                                (2-D default 0.02: 1.1 deg; 3-D 0.04: 2.3 deg) */
    float recentre_rel;    /**< provisional centre moves when a survey differs by more than this x R
                                (0 < x <= 1, default 0.05) */
    float range_limit;     /**< sensor range in the sample unit: |axis| >= range_limit is saturated
                                and refused; 0 = not declared (no check) (default 0) */
    float level_band_rel;  /**< 2-D level band: a sample whose raw z is more than this x R from the
                                store's level model (file comment) is refused once its bin holds
                                half its cap; 0..0.5, 0 = off (default: off, opt-in, see
                                docs/calibrator.md "Level band"; 3-D: unused, 0) */
    float tilt_limit_deg;  /**< 2-D gravity level test (magcal_cont_push_g): a sample is LEVEL when
                                its accelerometer tilt is within this many degrees (g_x^2 + g_y^2
                                <= tan^2(limit) g_z^2) and |g|^2 is within g_band_rel of its
                                running level; 0..30, 0 = off (every sample UNKNOWN) (2-D default
                                2; 3-D: unused, 0) */
    float g_band_rel;      /**< that |g|^2 band, relative, 0 < x <= 1 (default 0.1: |g| within about
                                5 %: hard braking, acceleration, bumps are not level) */
} magcal_intake_cfg_t;

/** 2-D defaults: 36 sectors x 8, spacing 2 % of R, gravity level test 2 deg. */
#define MAGCAL_INTAKE_CFG_DEFAULT_2D {2u, 8u, 36u, 8u, 0.02f, 0.05f, 0.0f, 0.0f, 2.0f, 0.1f}
/** 3-D defaults: 10 bands (128 cells) x 4, spacing 4 % of R. */
#define MAGCAL_INTAKE_CFG_DEFAULT_3D {3u, 4u, 10u, 8u, 0.04f, 0.05f, 0.0f, 0.0f, 0.0f, 0.1f}

/** What push did with a sample. */
typedef enum {
    MAGCAL_INTAKE_STORED = 0,            /**< stored in a free slot of its bin */
    MAGCAL_INTAKE_REPLACED = 1,          /**< stored; its bin was full, the oldest sample there dropped */
    MAGCAL_INTAKE_REFUSED_SPACING = 2,   /**< too close to a sample already in its bin */
    MAGCAL_INTAKE_REFUSED_SATURATED = 3, /**< an axis at the range limit (status MAGCAL_ERR_SATURATED) */
    MAGCAL_INTAKE_REFUSED_NONFINITE = 4, /**< NaN or Inf (status MAGCAL_ERR_NONFINITE) */
    MAGCAL_INTAKE_REFUSED_LEVEL = 5,     /**< 2-D: raw z outside the level band (a pitched sample) */
    MAGCAL_INTAKE_REFUSED_TILTED = 6     /**< 2-D: not level, and its bin is full of level samples */
} magcal_intake_outcome_t;

/** Tilt code of a sample (magcal_intake_push_tilt; 2-D, from the accelerometer). */
typedef enum {
    MAGCAL_INTAKE_TILT_UNKNOWN = 0, /**< no gravity (magcal_intake_push): stored as not level */
    MAGCAL_INTAKE_TILT_LEVEL = 1,   /**< the sensor was level: preferred in its bin */
    MAGCAL_INTAKE_TILT_TILTED = 2   /**< tilted, or |g| off its level (accelerating): not level */
} magcal_intake_tilt_t;

/** Where the binning centre comes from. */
typedef enum {
    MAGCAL_INTAKE_CENTRE_NONE = 0,        /**< no survey yet: bins around the origin */
    MAGCAL_INTAKE_CENTRE_PROVISIONAL = 1, /**< trimmed-extreme midpoint of the stored samples */
    MAGCAL_INTAKE_CENTRE_INSTALLED = 2    /**< set by magcal_intake_set_centre (installed calibration) */
} magcal_intake_centre_t;

/** Counters (since init or reset). */
typedef struct {
    uint32_t pushed;            /**< samples offered */
    uint32_t stored;            /**< samples held now */
    uint32_t added;             /**< stored into a free slot */
    uint32_t replaced;          /**< stored over the oldest sample of a full bin */
    uint32_t refused_spacing;   /**< refused: minimum spacing */
    uint32_t refused_saturated; /**< refused: range limit */
    uint32_t refused_nonfinite; /**< refused: NaN / Inf */
    uint32_t rebinned;          /**< samples moved to another bin after a centre change */
    uint32_t rebin_dropped;     /**< of those, oldest samples dropped from a full target bin */
    uint32_t recentres;         /**< centre changes (surveys that moved it, set_centre calls) */
    uint32_t refused_level;     /**< refused: 2-D level band (pitched) */
    uint32_t refused_tilted;    /**< refused: not level, its bin full of level samples */
    uint32_t stored_level;      /**< LEVEL samples stored (added or replaced) */
} magcal_intake_counters_t;

/** Live progress. */
typedef struct {
    uint32_t stored;           /**< samples held */
    uint16_t bins;             /**< bins of the mask (2-D sectors, 3-D cells) */
    uint16_t bins_filled;      /**< bins with at least one sample on the ring */
    float fill_fraction;       /**< bins_filled / bins */
    float completion_pct;      /**< 0..100: bins at depth ceil(per_bin / 2), each counted up to it */
    float coverage_deg;        /**< 2-D: (sectors - longest empty run) x width; 3-D: 360 x fill_fraction */
    float missing_start_deg;   /**< 2-D: start of the longest empty run, heading convention atan2(-x, y) */
    float missing_width_deg;   /**< 2-D: its width (0 when every sector is filled); 3-D: 0 */
    magcal_vec3_t centre;      /**< binning centre (z = 0 in 2-D) */
    float radius;              /**< R used for the spacing: installed, else the survey's (0 = none yet) */
    magcal_intake_centre_t centre_source; /**< where the centre comes from */
    uint8_t rebinning;         /**< 1 while a re-bin sweep after a centre change is unfinished
                                    (the counts then mix bins of the old and the new centre) */
} magcal_intake_progress_t;

/** The survey's fit sums (private to the intake sweep; one block, so the per-slot update reaches
 * every sum from one base address). */
typedef struct {
    float fit_a[10]; /**< private: circle / sphere fit normal matrix, packed lower triangle (<= 4 x 4) */
    float fit_b[4];  /**< private: its right-hand side */
    float fit_zz;    /**< private: sum of |u|^4 (fit residual) */
    float ell_a[15]; /**< private: 2-D conic fit normal matrix, packed 5 x 5 */
    float ell_b[5];  /**< private: its right-hand side */
    float ell_tt;    /**< private: sum of its squared targets (residual) */
} magcal_intake_sums_t;

/** Instance. Allocate statically; all fields are private. */
typedef struct {
    magcal_intake_cfg_t cfg;       /**< private */
    uint32_t magic;                /**< private */
    magcal_intake_slot_t *slots;   /**< private: caller storage */
    /* the survey first: the sweep's per-slot path reaches these from the instance's address
     * (VLDR offsets up to 1020 B) */
    uint32_t sv_n;                 /**< private: samples seen by the current survey */
    float sv_hi[3][MAGCAL_INTAKE_TRIM]; /**< private: survey, largest values per axis, descending */
    float sv_lo[3][MAGCAL_INTAKE_TRIM]; /**< private: survey, smallest values per axis, ascending */
    uint32_t fit_n;                /**< private: samples in the survey's circle / sphere fit sums */
    magcal_intake_sums_t sums;     /**< private: the survey's fit sums */
    magcal_vec3_t ref_c;           /**< private: reference centre of the fit's normalisation and trim */
    float ref_r;                   /**< private: reference radius (0 = none yet) */
    uint8_t ref_fit;               /**< private: 1 when the reference is a ring fit */
    uint8_t ref_free;              /**< private: 1: a ring fit whose tight band holds under half the survey
                                        is not kept (sweep.c; magcal_intake_init: 0, the 2-D continuous
                                        calibrator sets 1, magcal_intake_reset keeps it) */
    uint16_t n_bins;               /**< private: bins of the mask */
    uint16_t n_bands;              /**< private: 3-D bands */
    uint16_t band_start[MAGCAL_INTAKE_MAX_BANDS + 1u]; /**< private: first cell of each band */
    float band_cos[MAGCAL_INTAKE_MAX_BANDS + 1u];      /**< private: cos(colatitude) of the band edges */
    uint8_t count[MAGCAL_INTAKE_MAX_BINS];             /**< private: samples per bin */
    uint8_t bin_gen[MAGCAL_INTAKE_MAX_BINS];           /**< private: centre generation a bin was swept at */
    uint8_t gen;                   /**< private: centre generation */
    uint8_t centre_source;         /**< private: magcal_intake_centre_t */
    uint8_t rebin_pending;         /**< private */
    magcal_vec3_t centre;          /**< private */
    float radius;                  /**< private */
    uint32_t seq;                  /**< private: push counter */
    uint32_t cursor;               /**< private: sweep position (slot index) */
    uint32_t sweeps;               /**< private: completed sweeps */
    magcal_intake_counters_t ctr;  /**< private */
    float lv_s[9];                 /**< private: level survey sums (store.c) */
    float lv_abc[3];               /**< private: level model z = a + b cos + c sin of the direction */
    uint16_t lv_bin;               /**< private: next bin of the level survey */
    uint8_t lv_gen;                /**< private: centre generation of the survey under way */
    uint8_t lv_ok;                 /**< private: 1 when lv_abc holds a model of centre generation lv_ok_gen */
    uint8_t lv_ok_gen;             /**< private */
    float ell_scratch[25];         /**< private: the conic fit's 5 x 5 system at a sweep's end, here
                                        and not on the stack (the drain's deep path: <= 512 B) */
    float tilt_tan2;               /**< private: tan^2(cfg.tilt_limit_deg), set at init (0 = off) */
    float sv_in[4];                /**< private: 2-D survey, samples inside a trimmed reference's band:
                                        sums of x, y (from its centre), squared distance, count (sweep.c) */
} magcal_intake_t;

/**
 * @brief Number of bins of a configuration (2-D: cfg->bins; 3-D: the cells of the igloo mask).
 * @param[in]  cfg  configuration.
 * @param[out] bins bin count.
 * @return MAGCAL_OK, MAGCAL_ERR_NULL, MAGCAL_ERR_ARG (dims or bins out of range, or more than
 *         MAGCAL_INTAKE_MAX_BINS cells).
 */
magcal_status_t magcal_intake_bins(const magcal_intake_cfg_t *cfg, uint16_t *bins);

/**
 * @brief Initialise an empty store (validates and copies the configuration).
 * @param[out] st      instance.
 * @param[in]  cfg     configuration.
 * @param[in]  slots   caller storage, kept until the store is no longer used.
 * @param[in]  n_slots its length: at least bins x per_bin (the MAGCAL_INTAKE_SLOTS_* macros).
 * @return MAGCAL_OK, MAGCAL_ERR_NULL, MAGCAL_ERR_ARG (a value out of its documented range),
 *         MAGCAL_ERR_WORKSPACE (n_slots too small).
 */
magcal_status_t magcal_intake_init(magcal_intake_t *st, const magcal_intake_cfg_t *cfg,
                                   magcal_intake_slot_t *slots, size_t n_slots);

/**
 * @brief Offer one raw sample (bounded work, see the file comment).
 * @param[in,out] st      initialised store.
 * @param[in]     m       raw sample (2-D: z is stored but not binned; the range check covers it).
 * @param[out]    outcome optional (NULL allowed): what was done with it.
 * @return MAGCAL_OK (stored, replaced or refused for spacing: see outcome), MAGCAL_ERR_SATURATED
 *         (an axis at cfg.range_limit; not stored, counted), MAGCAL_ERR_NONFINITE (not stored,
 *         counted), MAGCAL_ERR_NULL, MAGCAL_ERR_NOT_INITIALISED.
 */
magcal_status_t magcal_intake_push(magcal_intake_t *st, const magcal_vec3_t *m,
                                   magcal_intake_outcome_t *outcome);

/**
 * @brief As magcal_intake_push, with the sample's tilt code (2-D level preference, file comment;
 *        3-D: the code is ignored). magcal_intake_push is this with MAGCAL_INTAKE_TILT_UNKNOWN.
 * @param[in,out] st      initialised store.
 * @param[in]     m       raw sample.
 * @param[in]     tilt    magcal_intake_tilt_t; a value out of range counts as UNKNOWN.
 * @param[out]    outcome optional (NULL allowed); MAGCAL_INTAKE_REFUSED_TILTED: a non-level
 *                        sample whose bin holds cfg.per_bin level samples (not stored, counted).
 * @return as magcal_intake_push.
 */
magcal_status_t magcal_intake_push_tilt(magcal_intake_t *st, const magcal_vec3_t *m, magcal_intake_tilt_t tilt,
                                        magcal_intake_outcome_t *outcome);

/**
 * @brief Bin around an installed calibration's centre (re-bins the store over the next sweeps),
 *        or, with centre NULL, return to the provisional centre.
 * @param[in,out] st     initialised store.
 * @param[in]     centre hard-iron centre in the sample unit (2-D: z ignored), or NULL.
 * @param[in]     radius field radius around it (> 0) for the spacing; ignored when centre is NULL.
 * @return MAGCAL_OK, MAGCAL_ERR_NULL, MAGCAL_ERR_NOT_INITIALISED, MAGCAL_ERR_NONFINITE,
 *         MAGCAL_ERR_ARG (radius <= 0).
 */
magcal_status_t magcal_intake_set_centre(magcal_intake_t *st, const magcal_vec3_t *centre, float radius);

/**
 * @brief Complete the current sweep and the next one now (O(slots); task context), e.g. before a
 *        snapshot: the survey is applied and a re-bin it starts is finished.
 * @return MAGCAL_OK, MAGCAL_ERR_NULL, MAGCAL_ERR_NOT_INITIALISED.
 */
magcal_status_t magcal_intake_settle(magcal_intake_t *st);

/**
 * @brief Drop every sample and counter (a relearn after a change); centre back to provisional.
 * @return MAGCAL_OK, MAGCAL_ERR_NULL, MAGCAL_ERR_NOT_INITIALISED.
 */
magcal_status_t magcal_intake_reset(magcal_intake_t *st);

/**
 * @brief Live progress (O(slots): one squared distance per stored sample, the ring test above).
 * @return MAGCAL_OK, MAGCAL_ERR_NULL, MAGCAL_ERR_NOT_INITIALISED.
 */
magcal_status_t magcal_intake_progress(const magcal_intake_t *st, magcal_intake_progress_t *out);

/**
 * @brief Filled-bin mask: bit (b % 32) of words[b / 32] is set when bin b holds a sample on the
 *        ring (file comment; O(slots)).
 * @param[in]  st     initialised store.
 * @param[out] words  mask.
 * @param[in]  nwords its length, >= MAGCAL_INTAKE_MASK_WORDS(bins).
 * @return MAGCAL_OK, MAGCAL_ERR_NULL, MAGCAL_ERR_NOT_INITIALISED, MAGCAL_ERR_WORKSPACE.
 */
magcal_status_t magcal_intake_mask(const magcal_intake_t *st, uint32_t *words, size_t nwords);

/** @brief Counters. @return MAGCAL_OK, MAGCAL_ERR_NULL, MAGCAL_ERR_NOT_INITIALISED. */
magcal_status_t magcal_intake_counters(const magcal_intake_t *st, magcal_intake_counters_t *out);

/**
 * @brief Copy the stored samples, in bin order (deterministic), into caller memory for a solve.
 * @param[in]  st  initialised store.
 * @param[out] out samples (3-D), or magcal_intake_snapshot2 for the (x, y) components.
 * @param[in]  cap length of out; must be >= the stored count (progress.stored).
 * @param[out] n   samples written.
 * @return MAGCAL_OK, MAGCAL_ERR_NULL, MAGCAL_ERR_NOT_INITIALISED, MAGCAL_ERR_WORKSPACE (cap too
 *         small; nothing written).
 *
 * @code
 * #define SECTORS 36u
 * #define PER_BIN 8u
 * static magcal_intake_slot_t slots[MAGCAL_INTAKE_SLOTS_2D(SECTORS, PER_BIN)];
 * static magcal_vec2_t solve_buf[MAGCAL_INTAKE_SLOTS_2D(SECTORS, PER_BIN)];
 * static magcal_intake_t store;
 * const magcal_intake_cfg_t cfg = MAGCAL_INTAKE_CFG_DEFAULT_2D;
 * magcal_intake_progress_t p;
 * size_t n;
 * (void)magcal_intake_init(&store, &cfg, slots, sizeof(slots) / sizeof(slots[0]));
 * // per sample (ISR or task):  (void)magcal_intake_push(&store, &m, NULL);
 * // in the task:
 * (void)magcal_intake_progress(&store, &p);
 * if (p.coverage_deg >= 270.0f) {
 *     (void)magcal_intake_snapshot2(&store, solve_buf, sizeof(solve_buf) / sizeof(solve_buf[0]), &n);
 *     // fit solve_buf[0..n)
 * }
 * @endcode
 */
magcal_status_t magcal_intake_snapshot3(const magcal_intake_t *st, magcal_vec3_t *out, size_t cap, size_t *n);

/** @brief As magcal_intake_snapshot3, the (x, y) components. @return as magcal_intake_snapshot3. */
magcal_status_t magcal_intake_snapshot2(const magcal_intake_t *st, magcal_vec2_t *out, size_t cap, size_t *n);

#ifdef __cplusplus
}
#endif

#endif /* MAGCAL_INTAKE_H */
