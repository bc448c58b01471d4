/* Build configuration and version of the linked library (config.h): what a caller compiled
 * with is compared with what the library was compiled with. */
#include "magcal.h"

uint32_t magcal_config_fingerprint(void) { return MAGCAL_CONFIG_FINGERPRINT; }

magcal_status_t magcal_config_check_fingerprint(uint32_t caller_fingerprint)
{
    return (caller_fingerprint == (uint32_t)MAGCAL_CONFIG_FINGERPRINT) ? MAGCAL_OK
                                                                       : MAGCAL_ERR_CONFIG_MISMATCH;
}

uint32_t magcal_version(void) { return MAGCAL_VERSION; }

const char *magcal_version_str(void) { return MAGCAL_VERSION_STRING; }
