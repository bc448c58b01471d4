#!/usr/bin/python3
"""Synthetic 3-axis dumps with accelerometer and known truth for the tilt-compensation checks of
magcal-replay (tools/replay/tests/check_replay.py, cases tilt_3d, tilt_2d and outliers_3d).

    /usr/bin/python3 tools/gen_dump3d.py [--out tools/replay/tests/data]

Writes DIR/<scenario>.csv and DIR/<scenario>.json (fixed seeds: reproducible).

Model (algorithms.md 6, 7.1): body x right, y forward, z up; attitude C_b^ENU = Rz(-psi) Rx(theta)
Ry(phi); Earth field B (ENU) with horizontal intensity H and inclination I (down positive):
B_ENU = (0, H, -H tan I) (magnetic north = y of ENU, declination 0); raw field m = W C^T B + V + n;
accelerometer f = C^T (0, 0, 1) g + n_a (specific force in g; +1 on z when level).

Scenarios:
  tilt_tumble   rows [0, 600): static random orientations over the whole sphere (a 3-D
                calibration tumble); rows [600, 760): 16 headings x 10 with roll, pitch uniform
                in +-25 deg (verification); then 7 gate rows at heading 0: 3 accelerating
                (|f| = 1.3 g), 2 in free fall (|f| = 0.1 g), 2 at pitch 85 deg.
                W symmetric positive definite (the ellipsoid fit's symmetric G is then the true
                inverse up to scale), V = (12, -7, 20) uT.
  level_tilted  rows [0, 600): level calibration turn over 720 deg (accelerometer (0, 0, 1) g
                plus noise); rows [600, 760): 16 headings x 10 with roll, pitch uniform in +-10 deg.
                Soft iron only in x/y with det = 1 (so the 2-D calibration radius equals H and
                its M is the true inverse), z gain 1, V = (12, -7, 20) uT: the 2-D calibration
                plus the --inclination approximation is exact up to noise.
  tumble_outliers  tilt_tumble's W, V and layout (600 tumble rows, 160 tilted verification rows,
                no gate rows) with known outlier rows (column `outlier` = 1): 24 calibration rows
                (7, 32, 57, ...: every 25th) and 8 verification rows (605, 625, ...) get a field
                magnitude error of +-(10..30) % of F along m - V (alternating sign). Along m - V
                the true calibration's heading is unchanged, so floor_deg is the clean floor.
  tumble_burst  tilt_tumble's W, V and layout with a dense burst: rows 300-319 stuck at one reading
                80 % outside the shell (+ noise), and 10 spikes (25, 85, ...: every 60th) at
                3 F from V in random directions (column `outlier` = 1). The OPTICS density stage
                must take the burst out; the fit's residual gate alone accepts it.

Truth JSON: floor_deg = heading RMS on the verification rows with the TRUE calibration and the
same tilt formulas applied to the same noisy samples; gates = expected tilt gate counts over all
rows (the library's default gates: free fall 0.3 g, norm 0.08 g, pitch 80 deg) computed with the
true calibration.
"""
import json
import math
import os
import sys

import numpy as np

H, INCL = 20.0, 65.0  # uT, deg
SIGMA_M, SIGMA_A = 0.1, 0.003  # uT, g
V = np.array([12.0, -7.0, 20.0])
VER_H = [11.25 + 22.5 * k for k in range(16)]


def rx(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def ry(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def rz(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def c_b_enu(roll, pitch, yaw):
    return rz(-yaw) @ rx(pitch) @ ry(roll)


def b_enu():
    return np.array([0.0, H, -H * math.tan(math.radians(INCL))])


def tilt_heading(f, h):
    """algorithms.md 6 (same formulas as src/heading/tilt.c), degrees [0, 360)."""
    fx, fy, fz = f
    th = math.atan2(fy, math.hypot(fx, fz))
    ph = math.atan2(-fx, fz)
    lx = h[0] * math.cos(ph) + h[2] * math.sin(ph)
    ly = h[1] * math.cos(th) + math.sin(th) * (h[0] * math.sin(ph) - h[2] * math.cos(ph))
    return math.degrees(math.atan2(-lx, ly)) % 360.0, lx, ly


def gate(f, h):
    n = np.linalg.norm(f)
    if n < 0.3:
        return "free_fall"
    if abs(n - 1.0) > 0.08:
        return "accel_norm"
    if abs(f[1]) > n * math.sin(math.radians(80.0)):
        return "gimbal"
    _, lx, ly = tilt_heading(f, h)
    if math.hypot(lx, ly) <= 0.02 * np.linalg.norm(h):
        return "zero_field"
    return "ok"


def wrap180(a):
    return (a + 180.0) % 360.0 - 180.0


def make(name, rng):
    rows = []  # (roll, pitch, yaw, accel scale, ref)
    if name in ("tilt_tumble", "tumble_outliers", "tumble_burst"):
        A = np.array([[1.12, 0.05, -0.04], [0.05, 0.90, 0.06], [-0.04, 0.06, 1.02]])
        W = A  # symmetric positive definite
        for _ in range(600):
            q = rng.standard_normal(4)
            q /= np.linalg.norm(q)
            w, x, y, z = q
            R = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                          [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                          [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
            rows.append(dict(C=R, scale=1.0, ref=float("nan")))
        tilt = 25.0
        n_cal = 600
    else:
        k = 1.1
        phi = math.radians(25.0)
        R2 = np.array([[math.cos(phi), -math.sin(phi)], [math.sin(phi), math.cos(phi)]])
        T = R2 @ np.diag([k, 1.0 / k]) @ R2.T
        W = np.eye(3)
        W[:2, :2] = T
        inc = rng.uniform(0.5, 1.5, 600)
        cum = np.concatenate([[0.0], np.cumsum(inc)[:-1]]) / np.sum(inc)
        for psi in (17.0 + 720.0 * cum) % 360.0:
            rows.append(dict(C=c_b_enu(0.0, 0.0, math.radians(psi)), scale=1.0, ref=float(psi)))
        tilt = 10.0
        n_cal = 600
    for psi in np.repeat(VER_H, 10):
        r, p = rng.uniform(-tilt, tilt, 2)
        rows.append(dict(C=c_b_enu(math.radians(r), math.radians(p), math.radians(psi)), scale=1.0, ref=float(psi)))
    n_ver_end = len(rows)
    out_rows = []
    if name == "tumble_outliers":
        out_rows = list(range(7, n_cal, 25)) + list(range(n_cal + 5, n_ver_end, 20))
    burst_rows = list(range(300, 320)) if name == "tumble_burst" else []
    spike_rows = list(range(25, n_cal, 60)) if name == "tumble_burst" else []
    out_rows = out_rows + burst_rows + spike_rows
    burst_m = None
    if name == "tilt_tumble":
        for sc in (1.3, 1.3, 1.3, 0.1, 0.1):
            rows.append(dict(C=c_b_enu(0.05, 0.1, 0.0), scale=sc, ref=0.0))
        for _ in range(2):
            rows.append(dict(C=c_b_enu(0.0, math.radians(85.0), 0.0), scale=1.0, ref=0.0))
    Winv = np.linalg.inv(W)
    out, gates, errs = [], {}, []
    for i, rw in enumerate(rows):
        C = rw["C"]
        h = C.T @ b_enu()
        m = W @ h + V + SIGMA_M * rng.standard_normal(3)
        if i in burst_rows:
            # a reading stuck 80 % outside the shell (driver glitch / magnet next to the sensor)
            if burst_m is None:
                burst_m = V + 1.8 * (m - V)
            m = burst_m + SIGMA_M * rng.standard_normal(3)
        elif i in spike_rows:
            d = rng.standard_normal(3)
            m = V + 3.0 * np.linalg.norm(m - V) * d / np.linalg.norm(d)
        elif i in out_rows:
            sgn = 1.0 if out_rows.index(i) % 2 == 0 else -1.0
            m = V + (1.0 + sgn * rng.uniform(0.10, 0.30)) * (m - V)
        f = rw["scale"] * (C.T @ np.array([0.0, 0.0, 1.0])) + SIGMA_A * rng.standard_normal(3)
        ht = Winv @ (m - V)
        g = gate(f, ht)
        gates[g] = gates.get(g, 0) + 1
        if n_cal <= i < n_ver_end:
            errs.append(wrap180(tilt_heading(f, ht)[0] - rw["ref"]))
        out.append((0.05 * i, m, f, rw["ref"], 1 if i in out_rows else 0))
    floor = math.sqrt(np.mean(np.square(errs)))
    lines = ["# scenario: %s" % name, "# h_horizontal_uT: %g" % H, "# inclination_deg: %g" % INCL,
             "# floor_deg: %.6g" % floor, "t,mx,my,mz,ax,ay,az,heading_ref_deg" + (",outlier" if out_rows else "")]
    for t, m, f, ref, o in out:
        lines.append("%.2f,%.5f,%.5f,%.5f,%.5f,%.5f,%.5f,%s" % (
            t, m[0], m[1], m[2], f[0], f[1], f[2], "nan" if math.isnan(ref) else "%.4f" % ref) +
            (",%d" % o if out_rows else ""))
    truth = dict(scenario=name, W=W.tolist(), V=V.tolist(), h_horizontal=H, inclination_deg=INCL,
                 F=float(np.linalg.norm(b_enu())), sigma_m=SIGMA_M, sigma_a=SIGMA_A, n_cal=n_cal,
                 verification=dict(rows=[n_cal, n_ver_end], headings_deg=VER_H, per_heading=10, tilt_deg=tilt),
                 n_rows=len(rows), floor_deg=floor, gates=gates,
                 note="heading = tilt-compensated (algorithms.md 6) with the TRUE W, V on the same samples")
    if out_rows:
        truth["outlier_rows"] = out_rows
        truth["n_cal_outliers"] = sum(1 for i in out_rows if i < n_cal)
    return "\n".join(lines) + "\n", truth


def main(argv):
    out = argv[argv.index("--out") + 1] if "--out" in argv else "tools/replay/tests/data"
    os.makedirs(out, exist_ok=True)
    for seed, name in ((201, "tilt_tumble"), (202, "level_tilted"), (203, "tumble_outliers"), (204, "tumble_burst")):
        csv, truth = make(name, np.random.default_rng(seed))
        with open(os.path.join(out, name + ".csv"), "w") as f:
            f.write(csv)
        with open(os.path.join(out, name + ".json"), "w") as f:
            json.dump(truth, f, indent=1)
            f.write("\n")
        print("%-14s rows=%d floor=%.4f deg gates=%s" % (name, truth["n_rows"], truth["floor_deg"], truth["gates"]))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
