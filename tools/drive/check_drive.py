#!/usr/bin/env python3
"""CTest `gen_drive` (label tool): tools/gen_drive.py keeps the statistics it promises, and the
intake store fed with its stream keeps to its bins.

    check_drive.py --gen tools/gen_drive.py --python /usr/bin/python3 --intake magcal_drive_intake
                   --workdir DIR [--minutes 20] [--seed 3]

The generator needs numpy (the given --python); without it the test is skipped (exit 77). This
script itself uses the standard library only. Exit 0 pass, 1 fail.
"""
import argparse
import csv
import hashlib
import json
import math
import os
import subprocess
import sys

FAILS = []


def check(cond, what):
    print(("ok   " if cond else "FAIL ") + what)
    if not cond:
        FAILS.append(what)


def runs(flags):
    """(start, length) of the runs of 1 in a 0/1 list."""
    out, s = [], None
    for i, f in enumerate(flags + [0]):
        if f and s is None:
            s = i
        elif not f and s is not None:
            out.append((s, i - s))
            s = None
    return out


def inv3(a):
    d = (a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1]) - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0])
         + a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0]))
    c = [[0.0] * 3 for _ in range(3)]
    for i in range(3):
        for j in range(3):
            r = [k for k in range(3) if k != j]
            s = [k for k in range(3) if k != i]
            m = a[r[0]][s[0]] * a[r[1]][s[1]] - a[r[0]][s[1]] * a[r[1]][s[0]]
            c[i][j] = (-1) ** (i + j) * m / d
    return c


def dcm(roll, pitch, yaw):
    """C_b^NED of include/magcal/aided.h (body x right, y forward, z up)."""
    cf, sf, ct, st, cp, sp = math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch), math.cos(yaw), math.sin(yaw)
    return [[-sp * cf + cp * st * sf, cp * ct, -sp * sf - cp * st * cf],
            [cp * cf + sp * st * sf, sp * ct, cp * sf - sp * st * cf],
            [ct * sf, -st, -ct * cf]]


def gen(a, minutes, seed, csv_path, json_path):
    cmd = [a.python, a.gen, "--minutes", str(minutes), "--seed", str(seed), "--out", csv_path]
    if json_path:
        cmd += ["--truth", json_path]
    p = subprocess.run(cmd, capture_output=True, text=True)
    if p.returncode != 0:
        print(p.stderr)
    return p.returncode


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--gen", required=True)
    ap.add_argument("--python", default="/usr/bin/python3")
    ap.add_argument("--intake", required=True)
    ap.add_argument("--workdir", required=True)
    ap.add_argument("--minutes", type=float, default=20.0)
    ap.add_argument("--seed", type=int, default=3)
    a = ap.parse_args()
    if subprocess.run([a.python, "-c", "import numpy"], capture_output=True).returncode != 0:
        print("skip: %s has no numpy" % a.python)
        return 77
    os.makedirs(a.workdir, exist_ok=True)
    dump = os.path.join(a.workdir, "drive.csv")
    truth_p = os.path.join(a.workdir, "drive.json")
    if gen(a, a.minutes, a.seed, dump, truth_p) != 0:
        check(False, "generator runs")
        return 1
    truth = json.load(open(truth_p))

    # ---- determinism: the same seed gives the same bytes
    h = []
    for k in range(2):
        p = os.path.join(a.workdir, "det%d.csv" % k)
        gen(a, 2.0, 11, p, None)
        h.append(hashlib.sha256(open(p, "rb").read()).hexdigest())
    check(h[0] == h[1], "same seed, same bytes (2-minute drive)")

    # ---- the promised statistics, recomputed from the CSV
    rows = []
    with open(dump) as f:
        lines = (l for l in f if not l.startswith("#"))
        for r in csv.DictReader(lines):
            rows.append(r)
    n = len(rows)
    rate = truth["rate_hz"]
    check(n == int(round(a.minutes * 60 * rate)) == truth["rows"], "rows = minutes x 60 x rate (%d)" % n)
    parked = [int(r["parked"]) for r in rows]
    frac = sum(parked) / n
    check(frac >= 0.30, "parked fraction %.3f >= 0.30" % frac)
    check(abs(frac - truth["parked_fraction"]) < 1e-9, "parked fraction matches the truth JSON")
    longest = max((l for _, l in runs(parked)), default=0) / rate
    check(longest <= 600.0 + 1e-9, "longest park %.1f s <= 10 min" % longest)
    pitch = [abs(float(r["pitch_deg"])) for r in rows]
    check(max(pitch) <= 6.0 + 1e-6 and max(pitch) >= 3.0, "hills: max |pitch| %.3f deg in [3, 6]" % max(pitch))
    dist = [int(r["disturbed"]) for r in rows]
    druns = runs(dist)
    check(len(druns) >= 1 and len(druns) <= len(truth["transients"]),
          "transient disturbances: %d runs, %d planned" % (len(druns), len(truth["transients"])))
    single = [l for s, l in druns if sum(1 for t in truth["transients"] if t[0] <= s + l and t[1] >= s) == 1]
    check(all(2.0 * rate <= l <= 5.0 * rate + 1 for l in single), "each separate transient lasts 2..5 s")
    check(sum(dist) == truth["disturbed_rows"], "disturbed rows match the truth JSON")
    # +30 % field at the peak of each separate transient: |m - (W C^T B + V)| / F = 0.3
    W = inv3(truth["cal_before"]["g"])
    F = truth["field_ut"]
    peaks = []
    for s0, l in druns:
        k = s0 + l // 2
        r = rows[k]
        if int(r["glitch"]) != 0 or l not in single:
            continue
        c = dcm(*(math.radians(float(r[q])) for q in ("roll_deg", "pitch_deg", "yaw_deg")))
        h = [sum(c[j][i] * truth["b_ned_ut"][j] for j in range(3)) for i in range(3)]
        v = truth["cal_after" if int(r["step"]) else "cal_before"]["v"]
        mc = [sum(W[i][j] * h[j] for j in range(3)) + v[i] for i in range(3)]
        d = math.sqrt(sum((float(r[q]) - mc[i]) ** 2 for i, q in enumerate(("mx", "my", "mz"))))
        peaks.append(d / F)
    check(len(peaks) >= 1 and all(abs(x - 0.3) < 0.02 for x in peaks),
          "transient peak field / |B|: %s (0.30 planned)" % ", ".join("%.3f" % x for x in peaks))
    segs = truth["segments"]
    check(truth["loops_360"] <= max(1, segs["turn"] // 4), "few full circles: %d loops in %d turns" % (truth["loops_360"], segs["turn"]))
    g0 = rows[0]
    m0 = math.sqrt(sum(float(g0[k]) ** 2 for k in ("mx", "my", "mz")))
    check(int(g0["glitch"]) == 1 and m0 > 300.0, "row 0 is a glitch (|m| = %.0f uT)" % m0)
    step = [int(r["step"]) for r in rows]
    check(truth["step_row"] == n // 2 and all(s == 0 for s in step[:n // 2]) and all(s == 1 for s in step[n // 2:]),
          "hard-iron step at the middle row %d" % (n // 2))
    rng = truth["sensor_range_ut"]
    rail = sum(1 for r in rows if max(abs(float(r[k])) for k in ("mx", "my", "mz")) >= rng)
    check(rail == truth["rail_rows"] and rail > 0, "rail (saturated) rows %d match the truth JSON" % rail)
    check(truth["turning_total_deg"] > 360.0, "turning %.0f deg" % truth["turning_total_deg"])

    # ---- the intake store fed with the stream (one push per row, file order)
    p = subprocess.run([a.intake, "--range", str(rng), dump], capture_output=True, text=True)
    check(p.returncode == 0, "magcal_drive_intake runs")
    if p.returncode != 0:
        print(p.stderr)
        return 1
    rep = json.loads(p.stdout)
    print(json.dumps({k: rep[k] for k in ("at_step_2d", "end_2d", "end_3d")}, indent=1))
    e2, e3, s2 = rep["end_2d"], rep["end_3d"], rep["at_step_2d"]
    check(e2["pushed"] == n and e3["pushed"] == n, "every row pushed")
    check(e2["refused_saturated"] == rail and e3["refused_saturated"] == rail,
          "every saturated row refused (2-D %d, 3-D %d, rail %d)" % (e2["refused_saturated"], e3["refused_saturated"], rail))
    check(e2["parks"] >= 2, "parks seen: %d" % e2["parks"])
    check(e2["park_max_sectors"] <= 2, "a park stores into at most 2 sectors (its own): %d" % e2["park_max_sectors"])
    check(e2["park_max_stored"] <= 16 and e3["park_max_stored"] <= 8,
          "a park stores at most 2 bins' worth (2-D %d, 3-D %d)" % (e2["park_max_stored"], e3["park_max_stored"]))
    # the store's provisional 2-D centre before the step: the level ring's centre V + W (0, 0, h_z)
    v = truth["cal_before"]["v"]
    hz = -truth["b_ned_ut"][2]
    cx, cy = v[0] + W[0][2] * hz, v[1] + W[1][2] * hz
    hF = math.hypot(truth["b_ned_ut"][0], truth["b_ned_ut"][1])
    err = math.hypot(s2["centre"][0] - cx, s2["centre"][1] - cy)
    check(s2["centre_source"] == 1 and err < 0.15 * hF,
          "2-D provisional centre at the step %.1f uT from the level ring's centre (< 15 %% of H = %.1f)" % (err, hF))
    # the store's live coverage before the step against the drive's own: 10-degree bins of the true
    # heading over the rows before it, 360 minus the longest empty circular run (the store bins the
    # magnetic heading: declination and soft iron shift each edge of the gap by a few degrees)
    occ = [0] * 36
    for r in rows[:n // 2]:
        occ[int((float(r["heading_ref_deg"]) % 360.0) // 10.0) % 36] = 1
    gap = run = 0
    for k in range(72):
        run = 0 if occ[k % 36] else run + 1
        gap = max(gap, min(run, 36))
    true_cov = 360.0 - 10.0 * gap
    check(abs(s2["coverage_deg"] - true_cov) <= 20.0,
          "2-D coverage before the step %.0f deg, the drive's true heading coverage %.0f deg (within a sector "
          "per gap edge)" % (s2["coverage_deg"], true_cov))
    # a car's hills (+-6 deg) never make a sphere: the 3-D store keeps the raw-origin bins
    check(e3["centre_source"] == 0, "3-D store: no sphere centre from car motion (source %d)" % e3["centre_source"])
    if FAILS:
        print("%d check(s) failed" % len(FAILS))
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
