#!/usr/bin/python3
"""Synthetic INS/GNSS-aided drive with known truth for magcal-replay --mode aided
(tools/replay/tests/check_replay.py, case aided).

    /usr/bin/python3 tools/gen_aided_dump.py [--out tools/replay/tests/data] [--level]

Writes DIR/aided_road.csv and DIR/aided_road.json (fixed seed: reproducible); with --level
DIR/aided_level.{csv,json} instead (below).

Same set-up as tests/test_aided.c (algorithms.md 7.1, 7.7): m = W C_n^b B_ref + V + n with
W = C_si C_no C_sf C_mis (soft iron, non-orthogonality, scale factors, 2/-1.5/1 deg misalignment),
V = (18, -11, 27) uT, sigma_m = 0.05 uT. Road-like drive at 1 Hz: straight legs of 60 epochs
(yaw wandering +-2 deg) joined by 90-degree turns over 15 epochs (3 right, 1 left), pitch and roll
AR(1) with 1 deg RMS; the INS attitude in the dump carries white errors of 0.01 deg (roll, pitch)
and 0.05 deg (yaw). Rows [0, 2000) calibrate; rows [2000, 2400) continue the drive and verify
(heading_ref_deg = the TRUE yaw, i.e. the true heading).

Reference field: the site is fixed (lat 48.1, lon 11.6, 0.5 km above the ellipsoid, decimal year
2026.5), so B_ref is one vector. Its value is WMM2025 at that site as printed by the library's own
CLI, `build/dev/tools/geomag/magcal-geomag 48.1 11.6 0.5 2026.5`:
X = 21036.072, Y = 1592.762, Z = 44001.344 nT (D = 4.3299 deg). The harness evaluates WMM2025
itself from the lat/lon/height/decimal_year columns; check_replay.py asserts it gets this vector.

DOP: 1.2, except 50 epochs (rows 500-549) at 5.0, which the default gate (3) must reject.

Columns: t (s), mx, my, mz (uT), roll_deg, pitch_deg, yaw_deg (aided.h convention), lat_deg,
lon_deg, height_km, decimal_year, dop, heading_ref_deg.

--level (aided_level, check_replay.py case aided_prior): the same sensor, site and road pattern, but
the calibration rows [0, 1200) are EXACTLY level (true and INS roll = pitch = 0, no INS tilt noise,
DOP 1.2 throughout): the z scale and the cross terms against z are unobservable (algorithms.md 7.7)
and come from the prior. Rows [1200, 1500) verify at tilt: roll and pitch uniform in +-15 deg per
row (INS errors as above). floor_deg as above (TRUE W^-1, V on the verification rows).
"""
import json
import math
import os
import sys

import numpy as np

B_NED_NT = np.array([21036.072, 1592.762, 44001.344])
SITE = (48.1, 11.6, 0.5, 2026.5)
V_TRUE = np.array([18.0, -11.0, 27.0])
N_CAL, N_ROWS = 2000, 2400
SIGMA_M = 0.05
D2R = math.pi / 180.0


def rot(axis, a):
    c, s = math.cos(a), math.sin(a)
    if axis == 0:
        return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    if axis == 1:
        return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def dcm_ned(roll, pitch, yaw):
    """C_b^NED for body x right, y forward, z up: P Rz(-yaw) Rx(pitch) Ry(roll)."""
    P = np.array([[0, 1, 0], [1, 0, 0], [0, 0, -1]])
    return P @ rot(2, -yaw) @ rot(0, pitch) @ rot(1, roll)


def make_w():
    si = np.array([[1.05, 0.04, -0.03], [0.04, 0.97, 0.05], [-0.03, 0.05, 1.02]])
    no = np.array([[1, 0, 0], [0.01, 1, 0], [-0.015, 0.02, 1]])
    sf = np.diag([1.1, 0.93, 1.04])
    mis = rot(2, 2.0 * D2R) @ rot(0, -1.5 * D2R) @ rot(1, 1.0 * D2R)
    return si @ no @ sf @ mis


def heading_deg(h, roll, pitch):
    cf, sf, ct, st = math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch)
    lx = h[0] * cf + h[2] * sf
    ly = h[1] * ct + st * (h[0] * sf - h[2] * cf)
    return math.degrees(math.atan2(-lx, ly))


HEADER = "t,mx,my,mz,roll_deg,pitch_deg,yaw_deg,lat_deg,lon_deg,height_km,decimal_year,dop,heading_ref_deg"


def road_yaw(k, yaw, leg):
    """Straight legs of 60 epochs joined by 90-degree turns over 15 epochs (3 right, 1 left)."""
    ph = k % 75
    if ph >= 60:
        yaw += (-1.0 if leg % 4 == 3 else 1.0) * 6.0 * D2R
        if ph == 74:
            leg += 1
    return yaw, leg


def main(argv):
    out = argv[argv.index("--out") + 1] if "--out" in argv else "tools/replay/tests/data"
    if "--level" in argv:
        return main_level(out)
    rng = np.random.default_rng(2025)
    W = make_w()
    Wi = np.linalg.inv(W)
    B = B_NED_NT * 1e-3  # uT
    decl = math.degrees(math.atan2(B[1], B[0]))
    a = 0.98
    drive = math.sqrt(1 - a * a) * 1.0 * D2R
    yaw, pitch, roll, leg = 10.0 * D2R, 0.0, 0.0, 0
    lines = ["# scenario: aided_road (tools/gen_aided_dump.py)", HEADER]
    errs = []
    for k in range(N_ROWS):
        yaw, leg = road_yaw(k, yaw, leg)
        pitch = a * pitch + drive * rng.standard_normal()
        roll = a * roll + drive * rng.standard_normal()
        y_true = yaw + 2.0 * D2R * math.sin(0.1 * k)
        h = dcm_ned(roll, pitch, y_true).T @ B
        m = W @ h + V_TRUE + SIGMA_M * rng.standard_normal(3)
        r_ins = roll + 0.01 * D2R * rng.standard_normal()
        p_ins = pitch + 0.01 * D2R * rng.standard_normal()
        y_ins = y_true + 0.05 * D2R * rng.standard_normal()
        dop = 5.0 if 500 <= k < 550 else 1.2
        ref = math.degrees(y_true) % 360.0
        if k >= N_CAL:
            e = heading_deg(Wi @ (m - V_TRUE), r_ins, p_ins) + decl - ref
            errs.append((e + 180.0) % 360.0 - 180.0)
        lines.append("%d,%.5f,%.5f,%.5f,%.5f,%.5f,%.5f,%.4f,%.4f,%.3f,%.4f,%.1f,%.5f" % (
            k, m[0], m[1], m[2], math.degrees(r_ins), math.degrees(p_ins), math.degrees(y_ins) % 360.0,
            SITE[0], SITE[1], SITE[2], SITE[3], dop, ref))
    floor = math.sqrt(np.mean(np.square(errs)))
    truth = dict(scenario="aided_road", W=W.tolist(), G_true=Wi.tolist(), V=V_TRUE.tolist(),
                 b_ref_ned_uT=B.tolist(), declination_deg=decl, site=SITE, sigma_m=SIGMA_M,
                 tilt_rms_deg=1.0, n_cal=N_CAL, n_rows=N_ROWS, dop_gated=50,
                 verification=dict(rows=[N_CAL, N_ROWS]), floor_deg=floor,
                 note="floor_deg: heading RMS on the verification rows with the TRUE W^-1, V, the dump's "
                      "INS roll/pitch and the WMM declination, against heading_ref_deg (true yaw)")
    return write_dump(out, lines, truth)


N_CAL_LEVEL, N_ROWS_LEVEL, TILT_LEVEL = 1200, 1500, 15.0


def write_dump(out, lines, truth):
    """OUT/<scenario>.csv and OUT/<scenario>.json (truth)."""
    name = truth["scenario"]
    os.makedirs(out, exist_ok=True)
    with open(os.path.join(out, name + ".csv"), "w") as f:
        f.write("\n".join(lines) + "\n")
    with open(os.path.join(out, name + ".json"), "w") as f:
        json.dump(truth, f, indent=1)
        f.write("\n")
    print("%s rows=%d floor=%.4f deg decl=%.4f deg" % (name, truth["n_rows"], truth["floor_deg"],
                                                        truth["declination_deg"]))
    return 0


def main_level(out):
    rng = np.random.default_rng(2026)
    W = make_w()
    Wi = np.linalg.inv(W)
    B = B_NED_NT * 1e-3  # uT
    decl = math.degrees(math.atan2(B[1], B[0]))
    yaw, leg = 10.0 * D2R, 0
    lines = ["# scenario: aided_level (tools/gen_aided_dump.py --level)", HEADER]
    errs = []
    for k in range(N_ROWS_LEVEL):
        yaw, leg = road_yaw(k, yaw, leg)
        y_true = yaw + 2.0 * D2R * math.sin(0.1 * k)
        if k < N_CAL_LEVEL:
            roll = pitch = 0.0
        else:
            roll, pitch = rng.uniform(-TILT_LEVEL, TILT_LEVEL, 2) * D2R
        h = dcm_ned(roll, pitch, y_true).T @ B
        m = W @ h + V_TRUE + SIGMA_M * rng.standard_normal(3)
        if k < N_CAL_LEVEL:
            r_ins = p_ins = 0.0
        else:
            r_ins = roll + 0.01 * D2R * rng.standard_normal()
            p_ins = pitch + 0.01 * D2R * rng.standard_normal()
        y_ins = y_true + 0.05 * D2R * rng.standard_normal()
        ref = math.degrees(y_true) % 360.0
        if k >= N_CAL_LEVEL:
            e = heading_deg(Wi @ (m - V_TRUE), r_ins, p_ins) + decl - ref
            errs.append((e + 180.0) % 360.0 - 180.0)
        lines.append("%d,%.5f,%.5f,%.5f,%.5f,%.5f,%.5f,%.4f,%.4f,%.3f,%.4f,%.1f,%.5f" % (
            k, m[0], m[1], m[2], math.degrees(r_ins), math.degrees(p_ins), math.degrees(y_ins) % 360.0,
            SITE[0], SITE[1], SITE[2], SITE[3], 1.2, ref))
    floor = math.sqrt(np.mean(np.square(errs)))
    truth = dict(scenario="aided_level", W=W.tolist(), G_true=Wi.tolist(), V=V_TRUE.tolist(),
                 b_ref_ned_uT=B.tolist(), declination_deg=decl, site=SITE, sigma_m=SIGMA_M,
                 tilt_cal_deg=0.0, tilt_verify_deg=TILT_LEVEL, n_cal=N_CAL_LEVEL, n_rows=N_ROWS_LEVEL,
                 verification=dict(rows=[N_CAL_LEVEL, N_ROWS_LEVEL]), floor_deg=floor,
                 note="calibration rows exactly level (unobservable z terms); floor_deg: heading RMS on the "
                      "verification rows with the TRUE W^-1, V, the dump's INS roll/pitch and the WMM declination")
    return write_dump(out, lines, truth)


if __name__ == "__main__":
    sys.exit(main(sys.argv))
