#!/usr/bin/python3
"""Long synthetic car drives with known truth, in stream form, for the continuous calibrator
(issue 13) and the intake store (include/magcal/intake.h).

    /usr/bin/python3 tools/gen_drive.py [--minutes 60] [--seed 1] [--rate 50] [--out FILE|-]
                                        [--truth FILE.json] [--no-step] [--dyn-accel]

Writes the dump CSV to FILE (default: stdout, row by row, so hours never sit in memory) and the
truth to FILE.json. Python 3 + numpy only; the same seed gives the same bytes. Nothing generated is
stored in the repository (the CTest `gen_drive` makes a short drive in the build tree).

Model (units uT, body x right, y forward, z up; include/magcal/aided.h conventions):
  m = W C_n^b B + V + d + n,   B = WMM2025 at 48.1 N 11.6 E, 0.5 km, 2026.5 (the site of
  tools/gen_aided_dump.py: X 21.036, Y 1.593, Z 44.001 uT, declination 4.33 deg), n ~ N(0, 0.1^2)
  per axis, W = soft iron x scale x misalignment (the truth JSON gives W^-1 as G), V the hard iron.
The drive is a sequence of segments:
  - park: 15 s .. 2 min (7 in 10) or 2 .. 10 min, the car stands still (attitude fixed, field
    noise only); parks are added until at least --parked-min (0.33) of the time is parked;
  - straight: 10 s .. 4 min, heading wandering +-1.5 deg (lane changes, curvature);
  - turn: a random angle (mostly 15 .. 200 deg, either sense; 1 in 12 turns is a loop of 360 ..
    420 deg, so few full circles), 8 .. 25 deg/s;
  - hills: pitch follows a smooth random profile bounded to +-6 deg while moving (held while
    parked), roll +-1.5 deg (camber); --hills DEG sets the pitch bound (the roll's is a quarter
    of it; the same draws, so only the attitude columns and what they move differ).
Disturbances (truth columns):
  - glitch: row 0 is a spike (a driver start-up glitch) and about one burst per 8 minutes of
    5 .. 40 rows is a driver glitch: one axis stuck at the sensor rail (+-sensor_range_ut: a
    saturated reading) or random garbage far off the sphere;
  - disturbed: about one per 4 minutes, 2 .. 5 s of an external field of 30 % of |B| in a fixed
    random body direction (a passing truck, a bridge), raised-cosine envelope;
  - step: from the middle row on, the hard iron changes by V_step (a magnet attached near the
    sensor: |V_step| about 40 % of |B|); 0 before, 1 from then on (--no-step: never).
Vehicle dynamics (--dyn-accel; off by default, so every drive is byte-identical to the generator
without it): the accelerometer reads the car's own acceleration too, in body axes (the road
plane; its pitch and roll are small): lateral v * yaw rate (centripetal, toward the turn's centre:
+x in a right turn) and longitudinal dv/dt (+y accelerating). The speed profile follows the
segments: 0 parked; a cruise of 8 .. 25 m/s per straight; a turn at the speed its peak yaw rate
allows at a lateral limit of 1.5 .. 3.5 m/s^2 (at most the cruise); between them the car brakes
at up to 2.5 m/s^2 (before a park or a turn: the ramp lies in the segment before) and
accelerates at up to 1.8 m/s^2 (after), rounded over 0.5 s (it stands 0.5 s either side of a park). Its random draws come from a
generator of their own (seed + 104729): the magnetometer, attitude and truth columns stay the
same bytes with and without it. Not modelled: body roll on the springs, road bumps.
Gyro (--gyro; off by default, the other columns are the same bytes with and without it): gx, gy,
gz appended, the body rates (rad/s, body axes as m) from the attitude's derivative, with a constant
bias of up to 0.5 deg/s and a scale error of up to 1 % per axis and 0.1 deg/s RMS of white noise
per sample, drawn from a generator of their own (seed + 15485863).
Columns: t, mx, my, mz, ax, ay, az (g, specific force: (0, 0, 1) level at rest), roll_deg,
pitch_deg, yaw_deg (true attitude), lat_deg, lon_deg, height_km, decimal_year, dop (so
`magcal-replay --mode aided` can read it), heading_ref_deg (TRUE heading = yaw), glitch,
disturbed, step, parked. docs/replay.md describes the format; `glitch` is the replay's truth flag.
"""
import argparse
import json
import math
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from gen_aided_dump import rot  # noqa: E402  (one rotation helper for both generators)

B_NED = np.array([21.036072, 1.592762, 44.001344])  # uT, WMM2025 at SITE (see gen_aided_dump.py)
SITE = (48.1, 11.6, 0.5, 2026.5)
D2R = math.pi / 180.0
SIGMA_M = 0.1
SENSOR_RANGE = 800.0  # uT: the declared range of the simulated magnetometer
GYRO_BIAS = 0.5    # deg/s: bound of the gyro's constant bias per axis (--gyro)
GYRO_SCALE = 0.01  # bound of its scale error per axis
GYRO_NOISE = 0.1   # deg/s RMS per sample
HEADER = ("t,mx,my,mz,ax,ay,az,roll_deg,pitch_deg,yaw_deg,lat_deg,lon_deg,height_km,decimal_year,"
          "dop,heading_ref_deg,glitch,disturbed,step,parked")


def dcm_ned_batch(roll, pitch, yaw):
    """C_b^NED (n x 3 x 3) for body x right, y forward, z up (aided.h): P Rz(-yaw) Rx(pitch) Ry(roll)."""
    cf, sf = np.cos(roll), np.sin(roll)
    ct, st = np.cos(pitch), np.sin(pitch)
    cp, sp = np.cos(yaw), np.sin(yaw)
    c = np.empty((len(roll), 3, 3))
    c[:, 0, 0] = -sp * cf + cp * st * sf
    c[:, 0, 1] = cp * ct
    c[:, 0, 2] = -sp * sf - cp * st * cf
    c[:, 1, 0] = cp * cf + sp * st * sf
    c[:, 1, 1] = sp * ct
    c[:, 1, 2] = cp * sf - sp * st * cf
    c[:, 2, 0] = ct * sf
    c[:, 2, 1] = -st
    c[:, 2, 2] = -ct * cf
    return c


def make_w():
    si = np.array([[1.06, 0.03, -0.02], [0.03, 0.95, 0.04], [-0.02, 0.04, 1.01]])
    sf = np.diag([1.04, 0.97, 1.02])
    mis = rot(2, 1.5 * D2R) @ rot(0, -1.0 * D2R) @ rot(1, 0.8 * D2R)
    return si @ sf @ mis


def plan_segments(rng, n_total, rate, parked_min):
    """List of (kind, rows, turn_deg, rate_dps); parks fill up to parked_min of the time."""
    segs = []
    rows = 0
    parked = 0
    while rows < n_total:
        r = rng.random()
        need_park = parked < parked_min * max(rows, 1)
        if need_park or r < 0.12:
            # traffic lights and short stops (15 s .. 2 min), now and then a long one (up to 10 min)
            dur = rng.uniform(15.0, 120.0) if rng.random() < 0.7 else rng.uniform(120.0, 600.0)
            n = int(dur * rate)
            segs.append(("park", n, 0.0, 0.0))
            parked += n
        elif r < 0.55:
            segs.append(("straight", int(rng.uniform(10.0, 240.0) * rate), 0.0, 0.0))
        else:
            if rng.random() < 1.0 / 12.0:
                ang = rng.uniform(360.0, 420.0)
            else:
                ang = rng.uniform(15.0, 200.0)
            ang *= 1.0 if rng.random() < 0.5 else -1.0
            dps = rng.uniform(8.0, 25.0)
            segs.append(("turn", max(1, int(abs(ang) / dps * rate)), ang, dps))
        rows += segs[-1][1]
    return segs


G0 = 9.80665  # m/s^2 per g
DYN_CRUISE = (8.0, 25.0)   # m/s, per straight
DYN_LAT_MAX = (1.5, 3.5)   # m/s^2, a turn's lateral limit at its peak yaw rate, per turn
DYN_BRAKE = 2.5            # m/s^2, the largest deceleration
DYN_ACCEL = 1.8            # m/s^2, the largest acceleration
DYN_ROUND_S = 0.5          # s, the moving average that rounds the ramps' corners (jerk)


def speed_profile(segs, n, rate, seed):
    """Speed (m/s) per row for the segments: each row's target (parked 0, a straight's cruise, a
    turn's speed: lateral limit / peak yaw rate, at most the cruise before it), then limited to
    DYN_ACCEL forward in time and DYN_BRAKE backward (the car brakes before a stop or a turn and
    accelerates after), rounded over DYN_ROUND_S; it stands still from DYN_ROUND_S before a park
    to DYN_ROUND_S after it, so the rounding leaves it at 0 while parked."""
    drng = np.random.default_rng(seed + 104729)
    tgt = np.empty(n)
    parked = np.zeros(n, dtype=bool)
    k = 0
    cruise = 0.5 * (DYN_CRUISE[0] + DYN_CRUISE[1])
    for kind, rows, _, dps in segs:
        e = min(n, k + rows)
        if kind == "park":
            tgt[k:e] = 0.0
            parked[k:e] = True
        elif kind == "straight":
            cruise = drng.uniform(*DYN_CRUISE)
            tgt[k:e] = cruise
        else:
            w_peak = 1.5 * dps * D2R  # the smoothstep's peak rate: 1.5 x its mean
            tgt[k:e] = min(cruise, drng.uniform(*DYN_LAT_MAX) / w_peak)
        k = e
        if k >= n:
            break
    w = max(1, int(round(DYN_ROUND_S * rate)))
    # the car stands for w rows either side of a park too, so the rounding keeps it at 0 there
    hold = np.convolve(parked.astype(float), np.ones(2 * w + 1), mode="same") > 0.5
    tgt[hold] = 0.0
    dv_up = DYN_ACCEL / rate
    dv_dn = DYN_BRAKE / rate
    v = tgt.copy()
    for i in range(1, n):  # accelerate at most DYN_ACCEL
        if v[i] > v[i - 1] + dv_up:
            v[i] = v[i - 1] + dv_up
    for i in range(n - 2, -1, -1):  # brake at most DYN_BRAKE (ahead of a stop or a turn)
        if v[i] > v[i + 1] + dv_dn:
            v[i] = v[i + 1] + dv_dn
    if w > 1 and n > w:
        v = np.convolve(np.pad(v, (w // 2, w - 1 - w // 2), mode="edge"), np.ones(w) / w, mode="valid")
    v[parked] = 0.0
    return v


def smooth_profile(rng, n, rate, bound_deg, period_s):
    """Random smooth profile (sum of 3 sinusoids of random phase), scaled to +-bound."""
    t = np.arange(n) / rate
    p = np.zeros(n)
    for k in range(3):
        f = 1.0 / (period_s * (1.0 + 0.7 * k))
        p += rng.uniform(0.5, 1.0) * np.sin(2 * math.pi * f * t + rng.uniform(0, 2 * math.pi))
    m = np.max(np.abs(p)) if n else 1.0
    return np.clip(bound_deg * p / (m if m > 0 else 1.0), -bound_deg, bound_deg)


def main(argv):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--minutes", type=float, default=60.0)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--rate", type=float, default=50.0)
    ap.add_argument("--parked-min", type=float, default=0.33)
    ap.add_argument("--out", default="-")
    ap.add_argument("--truth", default=None)
    ap.add_argument("--no-step", action="store_true")
    ap.add_argument("--hills", type=float, default=6.0,
                    help="bound of the pitch profile in degrees (roll: a quarter of it); 0 = a flat drive")
    ap.add_argument("--gyro", action="store_true",
                    help="append the gyro's body rates gx, gy, gz in rad/s (file comment); off: the "
                         "columns are absent and every other byte is the same")
    ap.add_argument("--dyn-accel", action="store_true",
                    help="the accelerometer reads the car's lateral (v x yaw rate) and longitudinal "
                         "(dv/dt) acceleration (file comment); off: gravity and noise only")
    a = ap.parse_args(argv)
    if not (a.minutes > 0 and 5.0 <= a.rate <= 400.0 and 0.0 <= a.parked_min < 0.9):
        ap.error("minutes > 0, rate 5..400 Hz, parked-min 0..0.9")
    rng = np.random.default_rng(a.seed)
    rate = a.rate
    n_total = int(round(a.minutes * 60.0 * rate))
    segs = plan_segments(rng, n_total, rate, a.parked_min)

    # ---- attitude and flags, row by row (vectorised per segment, then concatenated: 8 floats a row)
    yaw_l, mov_l, park_l = [], [], []
    yaw = rng.uniform(0, 360.0)
    turning_total = 0.0
    loops = 0
    for kind, n, ang, _ in segs:
        if kind == "park":
            yaw_l.append(np.full(n, yaw))
            park_l.append(np.ones(n, dtype=np.int8))
        elif kind == "straight":
            t = np.arange(n) / rate
            wob = 1.5 * np.sin(2 * math.pi * t / rng.uniform(30.0, 90.0) + rng.uniform(0, 2 * math.pi))
            yaw_l.append(yaw + wob - wob[0])
            yaw = yaw_l[-1][-1]
            park_l.append(np.zeros(n, dtype=np.int8))
        else:
            s = (np.arange(n) + 1) / n
            yaw_l.append(yaw + ang * (3 * s * s - 2 * s * s * s))  # smooth in and out of the turn
            yaw += ang
            turning_total += abs(ang)
            loops += 1 if abs(ang) >= 360.0 else 0
            park_l.append(np.zeros(n, dtype=np.int8))
    yaw_deg = np.concatenate(yaw_l)[:n_total]
    parked = np.concatenate(park_l)[:n_total]
    n = len(yaw_deg)
    # hills: the profile advances only while moving (held while parked)
    moving_idx = np.cumsum(1 - parked) - 1
    moving_idx[moving_idx < 0] = 0
    n_move = int(max(1, np.sum(1 - parked)))
    pitch_m = smooth_profile(rng, n_move, rate, a.hills, 240.0)
    roll_m = smooth_profile(rng, n_move, rate, a.hills / 4.0, 120.0)
    pitch_deg = pitch_m[moving_idx]
    roll_deg = roll_m[moving_idx]

    # ---- vehicle dynamics (--dyn-accel): body-axis acceleration in g, lateral (x) and longitudinal (y)
    dyn = None
    if a.dyn_accel:
        speed = speed_profile(segs, n, rate, a.seed)
        yaw_rate = np.gradient(np.unwrap(yaw_deg * D2R)) * rate  # rad/s, + clockwise (a right turn)
        dyn = np.zeros((n, 3))
        dyn[:, 0] = speed * yaw_rate / G0  # centripetal, toward the turn's centre
        dyn[:, 1] = np.gradient(speed) * rate / G0

    # ---- truth calibration and the step
    W = make_w()
    F = float(np.linalg.norm(B_NED))
    v0 = np.array([18.0, -11.0, 27.0])
    v_step = np.array([14.0, -9.0, 10.0])  # |V_step| = 19.9 uT = 41 % of |B|
    step_row = n // 2 if not a.no_step else n
    step = (np.arange(n) >= step_row).astype(np.int8)

    # ---- disturbances: transients (2..5 s of 0.3 |B|) and glitch bursts
    disturbed = np.zeros(n, dtype=np.int8)
    dist_field = np.zeros((n, 3))
    transients = []
    n_tr = max(1, int(a.minutes / 4.0))
    for _ in range(n_tr):
        dur = int(rng.uniform(2.0, 5.0) * rate)
        s0 = int(rng.uniform(0.02, 0.98) * (n - dur))
        d = rng.standard_normal(3)
        d *= 0.3 * F / np.linalg.norm(d)
        env = 0.5 - 0.5 * np.cos(2 * math.pi * (np.arange(dur) + 0.5) / dur)
        dist_field[s0:s0 + dur] += env[:, None] * d
        disturbed[s0:s0 + dur] = 1
        transients.append([s0, s0 + dur])
    glitch = np.zeros(n, dtype=np.int8)
    glitch_vals = {}
    bursts = []
    n_b = max(1, int(a.minutes / 8.0))
    for _ in range(n_b):
        dur = int(rng.integers(5, 41))
        s0 = int(rng.uniform(0.02, 0.98) * (n - dur))
        if rng.random() < 0.5:
            ax = int(rng.integers(0, 3))
            sign = 1.0 if rng.random() < 0.5 else -1.0
            kind = "rail"
        else:
            kind = "garbage"
        for k in range(s0, s0 + dur):
            glitch[k] = 1
            if kind == "rail":
                glitch_vals[k] = ("rail", ax, sign)
            else:
                glitch_vals[k] = ("garbage", rng.uniform(-600.0, 600.0, 3))
        bursts.append([s0, s0 + dur, kind])
    glitch[0] = 1
    glitch_vals[0] = ("spike", np.array([350.0, -420.0, 510.0]))
    rails = sum(1 for v in glitch_vals.values() if v[0] == "rail")

    # ---- stream the rows
    out = sys.stdout if a.out == "-" else open(a.out, "w", newline="\n")
    out.write("# scenario: gen_drive seed %d, %.1f min at %g Hz (tools/gen_drive.py)\n" % (a.seed, a.minutes, rate))
    out.write(HEADER + (",gx,gy,gz" if a.gyro else "") + "\n")
    chunk = 20000
    noise_rng = np.random.default_rng(a.seed + 7919)
    if a.gyro:
        grng = np.random.default_rng(a.seed + 15485863)  # its own draws: the other columns stay the same
        g_bias = grng.uniform(-GYRO_BIAS, GYRO_BIAS, 3) * D2R
        g_scale = 1.0 + grng.uniform(-GYRO_SCALE, GYRO_SCALE, 3)
    lat, lon, hkm, dyear = SITE
    for c0 in range(0, n, chunk):
        c1 = min(n, c0 + chunk)
        r = roll_deg[c0:c1] * D2R
        p = pitch_deg[c0:c1] * D2R
        y = yaw_deg[c0:c1] * D2R
        C = dcm_ned_batch(r, p, y)
        h = np.einsum("nji,j->ni", C, B_NED)  # C^T B: body field
        m = h @ W.T + v0 + step[c0:c1, None] * v_step + dist_field[c0:c1] + SIGMA_M * noise_rng.standard_normal((c1 - c0, 3))
        # specific force (g): C^T (0, 0, -1)_NED, i.e. +1 g up when level
        acc = -C[:, 2, :] + 0.01 * noise_rng.standard_normal((c1 - c0, 3))
        if dyn is not None:
            acc = acc + dyn[c0:c1]
        if a.gyro:
            # body rates from the attitude's derivative: C_b^NED' = C [w]x (central differences)
            km = np.maximum(np.arange(c0, c1) - 1, 0)
            kp = np.minimum(np.arange(c0, c1) + 1, n - 1)
            cm = dcm_ned_batch(roll_deg[km] * D2R, pitch_deg[km] * D2R, yaw_deg[km] * D2R)
            cp = dcm_ned_batch(roll_deg[kp] * D2R, pitch_deg[kp] * D2R, yaw_deg[kp] * D2R)
            om = np.einsum("nji,njk->nik", C, (cp - cm) * (rate / (kp - km))[:, None, None])
            wb = np.stack([om[:, 2, 1], om[:, 0, 2], om[:, 1, 0]], axis=1)
            gyr = wb * g_scale + g_bias + GYRO_NOISE * D2R * grng.standard_normal((c1 - c0, 3))
        lines = []
        for i in range(c1 - c0):
            k = c0 + i
            mm = m[i]
            g = glitch_vals.get(k)
            if g is not None:
                if g[0] == "rail":
                    mm = mm.copy()
                    mm[g[1]] = g[2] * SENSOR_RANGE
                else:
                    mm = g[1]
            lines.append("%.3f,%.3f,%.3f,%.3f,%.4f,%.4f,%.4f,%.3f,%.3f,%.3f,%.1f,%.1f,%.1f,%.1f,1.2,%.3f,%d,%d,%d,%d\n" % (
                k / rate, mm[0], mm[1], mm[2], acc[i, 0], acc[i, 1], acc[i, 2], roll_deg[k], pitch_deg[k],
                yaw_deg[k] % 360.0, lat, lon, hkm, dyear, yaw_deg[k] % 360.0, glitch[k], disturbed[k], step[k],
                parked[k]))
            if a.gyro:
                lines[-1] = lines[-1][:-1] + ",%.5f,%.5f,%.5f\n" % (gyr[i, 0], gyr[i, 1], gyr[i, 2])
        out.write("".join(lines))
    if out is not sys.stdout:
        out.close()

    if a.truth:
        G = np.linalg.inv(W)
        truth = {
            "generator": "tools/gen_drive.py", "seed": a.seed, "minutes": a.minutes, "rate_hz": rate,
            "rows": n, "field_ut": F, "b_ned_ut": B_NED.tolist(),
            "declination_deg": math.degrees(math.atan2(B_NED[1], B_NED[0])),
            "inclination_deg": math.degrees(math.atan2(B_NED[2], math.hypot(B_NED[0], B_NED[1]))),
            "sensor_range_ut": SENSOR_RANGE, "sigma_ut": SIGMA_M,
            "cal_before": {"g": G.tolist(), "v": v0.tolist(), "field": F},
            "cal_after": {"g": G.tolist(), "v": (v0 + v_step).tolist(), "field": F},
            "step_row": int(step_row) if step_row < n else None,
            "parked_fraction": float(np.mean(parked)),
            "longest_park_s": float(max((s[1] for s in segs if s[0] == "park"), default=0) / rate),
            "max_abs_pitch_deg": float(np.max(np.abs(pitch_deg))),
            "turning_total_deg": turning_total, "loops_360": loops,
            "transients": transients, "glitch_bursts": bursts, "rail_rows": rails,
            "glitch_rows": int(np.sum(glitch)), "disturbed_rows": int(np.sum(disturbed)),
            "segments": {k: sum(1 for s in segs if s[0] == k) for k in ("park", "straight", "turn")},
        }
        if dyn is not None:
            lat = np.abs(dyn[:, 0])
            truth["dyn_accel"] = {
                "max_speed_mps": float(np.max(speed)), "mean_moving_speed_mps": float(np.mean(speed[parked == 0])),
                "max_lateral_g": float(np.max(lat)), "max_longitudinal_g": float(np.max(np.abs(dyn[:, 1]))),
                "rows_lateral_over_0.035g": int(np.sum(lat > 0.035)),  # 2 deg of apparent roll
                "rows_longitudinal_over_0.035g": int(np.sum(np.abs(dyn[:, 1]) > 0.035)),
            }
        with open(a.truth, "w") as f:
            json.dump(truth, f, indent=1)
            f.write("\n")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
