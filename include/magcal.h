/**
 * @file magcal.h
 * @brief Umbrella header of magcal: includes every module header and holds the version.
 *
 * The three MAGCAL_VERSION_* numbers below are the one source of the version: CMakeLists.txt
 * reads them into project(VERSION), so the package version, magcal.pc and this header agree.
 * magcal_version() (config.h) gives the version of the library actually linked.
 */
#ifndef MAGCAL_H
#define MAGCAL_H

#define MAGCAL_VERSION_MAJOR 0
#define MAGCAL_VERSION_MINOR 1
#define MAGCAL_VERSION_PATCH 0

/** The version as one number: major * 10000 + minor * 100 + patch. */
#define MAGCAL_VERSION                                                                             \
    ((uint32_t)MAGCAL_VERSION_MAJOR * 10000u + (uint32_t)MAGCAL_VERSION_MINOR * 100u +             \
     (uint32_t)MAGCAL_VERSION_PATCH)
#define MAGCAL_VERSION_STR_(x) #x
#define MAGCAL_VERSION_XSTR_(x) MAGCAL_VERSION_STR_(x)
/** "MAJOR.MINOR.PATCH", built from the three numbers. */
#define MAGCAL_VERSION_STRING                                                                      \
    MAGCAL_VERSION_XSTR_(MAGCAL_VERSION_MAJOR)                                                     \
    "." MAGCAL_VERSION_XSTR_(MAGCAL_VERSION_MINOR) "." MAGCAL_VERSION_XSTR_(MAGCAL_VERSION_PATCH)

#include "magcal/config.h"
#include "magcal/status.h"
#include "magcal/types.h"
#include "magcal/optics.h"
#include "magcal/dbscan.h"
#include "magcal/ellipse.h"
#include "magcal/heading.h"
#include "magcal/consensus.h"
#include "magcal/calibrator.h"
#include "magcal/geomag.h"
#include "magcal/ellipsoid.h"
#include "magcal/aided.h"
#include "magcal/tilt.h"
#include "magcal/swing.h"
#include "magcal/errmodel.h"
#include "magcal/intake.h"
#include "magcal/continuous.h"
#include "magcal/continuous3.h"
#include "magcal/record.h"

#endif /* MAGCAL_H */
