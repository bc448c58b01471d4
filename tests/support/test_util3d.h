/* 3-D helpers shared by the 3-D tests (double precision, test code only). */
#ifndef MAGCAL_TEST_UTIL3D_H
#define MAGCAL_TEST_UTIL3D_H

#include "magcal/ellipsoid.h"

/** c = a * b (3x3, row-major). */
void test_mat3_mul(double a[3][3], double b[3][3], double c[3][3]);
/** r = a^-1 (3x3, adjugate / determinant). */
void test_mat3_inv(double a[3][3], double r[3][3]);
/** Rotation by angle a (rad) about axis 0 = x, 1 = y, 2 = z (algorithms.md 6). */
void test_rot3(int axis, double a, double r[3][3]);
/** C_b^NED for body x right, y forward, z up: P Rz(-yaw) Rx(pitch) Ry(roll) (algorithms.md 6, 7.1). */
void test_dcm_ned(double roll, double pitch, double yaw, double c[3][3]);
/** The 3-D truth W = C_si * C_no * C_sf * C_mis used by test_ellipsoid.c and test_aided.c. */
void test_make_w_full(double w[3][3]);
/** ||G^T G - (W W^T)^-1||_F / ||(W W^T)^-1||_F of a calibration against the truth W: the shape
 *  error (G is W^-1 only up to a left rotation for an attitude-free fit). */
double test_q_err(const magcal_ellipsoid_cal_t *cal, double w[3][3]);

#endif
