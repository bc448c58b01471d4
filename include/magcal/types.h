/**
 * @file types.h
 * @brief Plain vector types and the axis/unit conventions used across magcal.
 *
 * Conventions (fixed once, used everywhere):
 * - body frame: x right, y forward, z up (right-handed);
 * - heading: degrees in [0, 360), clockwise seen from above, from magnetic north to the y axis;
 *   for a level, calibrated horizontal field h: heading = atan2(-h.x, h.y);
 * - declination: east positive; true heading = magnetic heading + declination;
 * - field: any consistent unit (raw LSB, uT, nT, gauss); headings depend only on ratios.
 */
#ifndef MAGCAL_TYPES_H
#define MAGCAL_TYPES_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/** A 2-D (horizontal) field sample: x right, y forward. */
typedef struct {
    float x;
    float y;
} magcal_vec2_t;

/** A 3-D sample: x right, y forward, z up. */
typedef struct {
    float x;
    float y;
    float z;
} magcal_vec3_t;

#ifdef __cplusplus
}
#endif

#endif /* MAGCAL_TYPES_H */
