/* Minimal consumer of the installed magcal package. */
#include <stdio.h>

#include "magcal.h"
#include "magcal/magcal_port.h"

int main(void)
{
    magcal_vec3_t m;
    magcal_status_t st = magcal_port_mag_read(&m);
    printf("magcal %s: first sample (%.1f, %.1f): %s\n", MAGCAL_VERSION_STRING, (double)m.x,
           (double)m.y, magcal_status_str(st));
    return st == MAGCAL_OK ? 0 : 1;
}
