/* 3-D helpers shared by the 3-D tests (see test_util3d.h). */
#include "test_util3d.h"

#include <math.h>
#include <string.h>

#define D2R (3.14159265358979323846 / 180.0)

void test_mat3_mul(double a[3][3], double b[3][3], double c[3][3])
{
    int i, j, k;
    for (i = 0; i < 3; ++i) {
        for (j = 0; j < 3; ++j) {
            c[i][j] = 0.0;
            for (k = 0; k < 3; ++k) {
                c[i][j] += a[i][k] * b[k][j];
            }
        }
    }
}

void test_mat3_inv(double a[3][3], double r[3][3])
{
    double det = a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1]) - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0]) +
                 a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0]);
    r[0][0] = (a[1][1] * a[2][2] - a[1][2] * a[2][1]) / det;
    r[0][1] = (a[0][2] * a[2][1] - a[0][1] * a[2][2]) / det;
    r[0][2] = (a[0][1] * a[1][2] - a[0][2] * a[1][1]) / det;
    r[1][0] = (a[1][2] * a[2][0] - a[1][0] * a[2][2]) / det;
    r[1][1] = (a[0][0] * a[2][2] - a[0][2] * a[2][0]) / det;
    r[1][2] = (a[0][2] * a[1][0] - a[0][0] * a[1][2]) / det;
    r[2][0] = (a[1][0] * a[2][1] - a[1][1] * a[2][0]) / det;
    r[2][1] = (a[0][1] * a[2][0] - a[0][0] * a[2][1]) / det;
    r[2][2] = (a[0][0] * a[1][1] - a[0][1] * a[1][0]) / det;
}

void test_rot3(int axis, double a, double r[3][3])
{
    double c = cos(a), s = sin(a);
    memset(r, 0, sizeof(double) * 9);
    if (axis == 0) {
        r[0][0] = 1;
        r[1][1] = c;
        r[1][2] = -s;
        r[2][1] = s;
        r[2][2] = c;
    } else if (axis == 1) {
        r[1][1] = 1;
        r[0][0] = c;
        r[0][2] = s;
        r[2][0] = -s;
        r[2][2] = c;
    } else {
        r[2][2] = 1;
        r[0][0] = c;
        r[0][1] = -s;
        r[1][0] = s;
        r[1][1] = c;
    }
}

/* C_b^NED for body x right, y forward, z up: P Rz(-yaw) Rx(pitch) Ry(roll) (algorithms.md 6, 7.1). */
void test_dcm_ned(double roll, double pitch, double yaw, double c[3][3])
{
    static double P[3][3] = {{0, 1, 0}, {1, 0, 0}, {0, 0, -1}};
    double rz[3][3], rx[3][3], ry[3][3], t1[3][3], t2[3][3];
    test_rot3(2, -yaw, rz);
    test_rot3(0, pitch, rx);
    test_rot3(1, roll, ry);
    test_mat3_mul(rz, rx, t1);
    test_mat3_mul(t1, ry, t2);
    test_mat3_mul(P, t2, c);
}

/* W = C_si * C_no * C_sf * C_mis (soft iron, non-orthogonality, scale, misalignment). */
void test_make_w_full(double w[3][3])
{
    static double si[3][3] = {{1.05, 0.04, -0.03}, {0.04, 0.97, 0.05}, {-0.03, 0.05, 1.02}};
    static double no[3][3] = {{1, 0, 0}, {0.01, 1, 0}, {-0.015, 0.02, 1}};
    static double sf[3][3] = {{1.1, 0, 0}, {0, 0.93, 0}, {0, 0, 1.04}};
    double mis[3][3], r1[3][3], r2[3][3], r3[3][3], t1[3][3], t2[3][3];
    test_rot3(2, 2.0 * D2R, r1);
    test_rot3(0, -1.5 * D2R, r2);
    test_rot3(1, 1.0 * D2R, r3);
    test_mat3_mul(r1, r2, t1);
    test_mat3_mul(t1, r3, mis);
    test_mat3_mul(si, no, t1);
    test_mat3_mul(t1, sf, t2);
    test_mat3_mul(t2, mis, w);
}

double test_q_err(const magcal_ellipsoid_cal_t *cal, double w[3][3])
{
    double wi[3][3], num = 0, den = 0;
    int i, j, k;
    test_mat3_inv(w, wi);
    for (i = 0; i < 3; ++i) {
        for (j = 0; j < 3; ++j) {
            double qt = 0, qh = 0;
            for (k = 0; k < 3; ++k) {
                qt += wi[k][i] * wi[k][j];
                qh += (double)cal->g[k][i] * cal->g[k][j];
            }
            num += (qh - qt) * (qh - qt);
            den += qt * qt;
        }
    }
    return sqrt(num / den);
}
