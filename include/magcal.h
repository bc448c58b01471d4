/**
 * @file magcal.h
 * @brief Umbrella header of magcal: includes every module header and holds the version.
 */
#ifndef MAGCAL_H
#define MAGCAL_H

#define MAGCAL_VERSION_MAJOR 0
#define MAGCAL_VERSION_MINOR 1
#define MAGCAL_VERSION_PATCH 0
#define MAGCAL_VERSION_STRING "0.1.0"

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

#endif /* MAGCAL_H */
