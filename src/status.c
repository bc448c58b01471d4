/* Status code names. */
#include "magcal/status.h"

const char *magcal_status_str(magcal_status_t status)
{
    switch (status) {
    case MAGCAL_OK: return "ok";
    case MAGCAL_ERR_NULL: return "null pointer";
    case MAGCAL_ERR_ARG: return "invalid argument";
    case MAGCAL_ERR_WORKSPACE: return "workspace too small";
    case MAGCAL_ERR_NONFINITE: return "non-finite input";
    case MAGCAL_ERR_TOO_FEW_POINTS: return "too few points";
    case MAGCAL_ERR_DEGENERATE: return "degenerate geometry";
    case MAGCAL_ERR_COVERAGE: return "arc coverage too small";
    case MAGCAL_ERR_HYPERBOLA: return "not an ellipse (hyperbola)";
    case MAGCAL_ERR_PARABOLA: return "not an ellipse (parabola)";
    case MAGCAL_ERR_IMAGINARY: return "imaginary or degenerate ellipse";
    case MAGCAL_ERR_ILL_CONDITIONED: return "ill-conditioned";
    case MAGCAL_ERR_BUFFER_FULL: return "buffer full";
    case MAGCAL_ERR_ALL_NOISE: return "every point is noise";
    case MAGCAL_ERR_TOO_MANY_OUTLIERS: return "too many outliers";
    case MAGCAL_ERR_RADIUS_RANGE: return "radius out of range";
    case MAGCAL_ERR_AXIS_RATIO: return "axis ratio too large";
    case MAGCAL_ERR_RESIDUAL: return "residual too large";
    case MAGCAL_ERR_NOT_BETTER: return "not better than current calibration";
    case MAGCAL_ERR_PORT: return "port read error";
    case MAGCAL_ERR_TIMEOUT: return "port timeout";
    case MAGCAL_ERR_NO_DATA: return "no more data";
    case MAGCAL_ERR_STATE: return "wrong state";
    case MAGCAL_ERR_NOT_INITIALISED: return "not initialised";
    case MAGCAL_ERR_FREE_FALL: return "free fall";
    case MAGCAL_ERR_ACCEL_NORM: return "accelerometer norm out of range";
    case MAGCAL_ERR_GIMBAL: return "pitch near +/-90 deg";
    case MAGCAL_ERR_SPREAD: return "reference headings badly spread";
    case MAGCAL_ERR_THRESHOLD: return "threshold not met at maximum order";
    case MAGCAL_ERR_OUT_OF_VALIDITY: return "outside model validity";
    case MAGCAL_ERR_NOT_ELLIPSOID: return "not an ellipsoid";
    case MAGCAL_ERR_UNOBSERVABLE: return "unobservable";
    case MAGCAL_ERR_NOT_CONVERGED: return "not converged";
    case MAGCAL_ERR_ZERO_FIELD: return "field too small";
    case MAGCAL_ERR_GATED: return "rejected by gate";
    case MAGCAL_ERR_NO_MOTION: return "no motion (sensor at rest: rotate it through many orientations)";
    case MAGCAL_ERR_SINGLE_AXIS: return "single rotation axis (turn about another axis too, or use the 2-D or aided calibration)";
    case MAGCAL_ERR_FIELD_MAGNITUDE: return "field magnitude implausible (check units, expected field, nearby iron)";
    case MAGCAL_ERR_CONFIG_MISMATCH: return "configuration mismatch";
    case MAGCAL_ERR_ALIGNMENT: return "misaligned buffer";
    case MAGCAL_ERR_CRC: return "record CRC mismatch";
    case MAGCAL_ERR_VERSION: return "record version mismatch";
    case MAGCAL_ERR_SATURATED: return "sample at the sensor range limit";
    case MAGCAL_ERR_INCONSISTENT: return "samples of more than one installation";
    case MAGCAL_ERR_SHAPE_CHANGED: return "soft-iron shape changed";
    case MAGCAL_IN_PROGRESS: return "in progress (call step again)";
    default: return "unknown";
    }
}

int magcal_status_is_outcome(magcal_status_t status)
{
    return (status == MAGCAL_OK || status == MAGCAL_ERR_NOT_BETTER || status == MAGCAL_ERR_GATED ||
            status == MAGCAL_ERR_NO_DATA || status == MAGCAL_ERR_NOT_CONVERGED ||
            status == MAGCAL_IN_PROGRESS)
               ? 1
               : 0;
}
