#!/usr/bin/python3
"""CTest check of `magcal-replay --stream --mode 3d` (the continuous 3-D calibrator, continuous3.h).

    check_stream3d.py --exe magcal-replay --source-dir REPO --work-dir DIR

On the bundled 3-D tumble tests/data/real/lsm9ds1_pmodnav_tumble.csv (534 rows, accelerometer in
m/s^2): every row goes through push + 16 steps (--steps-per-row 16: the solve is time-sliced) +
heading, then steps until the solve under way ends; the check asserts the stream contract of
docs/replay.md (headings CSV columns and trust names, generation = adoptions so far, JSON events
with rows in order, rows / trusted_rows), that the calibration in force at the end reaches the
|B| spread of the batch 3-D fit (`--mode 3d` on the same dump) over every row within +0.05
percentage points, and that a bad --mode is refused. Python standard library only.
"""
import argparse
import csv
import json
import math
import os
import subprocess
import sys

FAILS = []
TRUST = {"ok", "uncalibrated", "disturbed", "changed", "no_heading"}


def check(cond, msg):
    if not cond:
        FAILS.append(msg)
        sys.stderr.write("FAIL: %s\n" % msg)
    return cond


def rows(path):
    out = []
    with open(path, newline="") as f:
        for r in csv.DictReader(f):
            m = [float(r["mx"]), float(r["my"]), float(r["mz"])]
            if all(math.isfinite(v) for v in m):
                out.append(m)
    return out


def spread(G, V, ms):
    rs = []
    for m in ms:
        d = [m[i] - V[i] for i in range(3)]
        h = [sum(G[i][k] * d[k] for k in range(3)) for i in range(3)]
        rs.append(math.sqrt(sum(x * x for x in h)))
    mu = sum(rs) / len(rs)
    return math.sqrt(sum((r - mu) ** 2 for r in rs) / len(rs)) / mu


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--exe", required=True)
    ap.add_argument("--source-dir", required=True)
    ap.add_argument("--work-dir", required=True)
    a = ap.parse_args()
    os.makedirs(a.work_dir, exist_ok=True)
    dump = os.path.join(a.source_dir, "tests", "data", "real", "lsm9ds1_pmodnav_tumble.csv")
    hcsv = os.path.join(a.work_dir, "stream3d_headings.csv")
    # a control loop at 16 x the sample rate, as tests/test_shared_continuous3.c: this dump's store
    # has outliers, so its solves run the time-sliced density stage (~2,400 steps at the default
    # budget, docs/calibration_3d.md); at 4 steps per row its 534 rows end before the first one
    p = subprocess.run([a.exe, "--stream", "--mode", "3d", "--steps-per-row", "16", "--json", "--headings", hcsv, dump],
                       capture_output=True, text=True)
    check(p.returncode == 0, "stream 3d exit %d (stderr %s)" % (p.returncode, p.stderr.strip()))
    rep = json.loads(p.stdout)
    ms = rows(dump)
    check(rep.get("mode") == "3d", "mode %r" % rep.get("mode"))
    check(rep.get("rows") == len(ms) == 534, "rows %r (file %d)" % (rep.get("rows"), len(ms)))
    check(rep.get("tilt_compensated") is True, "m/s^2 accelerometer not used for tilt")
    gen = rep.get("generation", 0)
    check(gen >= 1, "no adoption on the bundled tumble")
    ev = rep.get("events", [])
    check(all(set(e) == {"row", "event", "status", "heading_err_deg"} for e in ev), "event fields")
    check(all(e["event"] in ("adopted", "refused", "change", "disturbance") for e in ev), "event names")
    check([e["row"] for e in ev] == sorted(e["row"] for e in ev), "events out of row order")
    adopted = [e["row"] for e in ev if e["event"] == "adopted"]
    check(len(adopted) == gen, "adopted events %d != generation %d" % (len(adopted), gen))
    # the estimated heading error of the calibration in force (the fit's own noise and predicted
    # parameter errors, as 2-D's est_heading_err_deg): the last adoption's
    est = rep.get("est_heading_err_deg")
    check(isinstance(est, (int, float)) and 0.0 < est < 15.0, "est_heading_err_deg %r" % est)
    last = [e for e in ev if e["event"] == "adopted"][-1:]
    check(bool(last) and last[0]["heading_err_deg"] == est, "last adopted event's heading_err_deg != est_heading_err_deg")
    with open(hcsv, newline="") as f:
        rd = csv.reader(f)
        head = next(rd)
        body = list(rd)
    check(head == ["index", "raw_heading_deg", "heading_deg", "trust", "generation"], "headings columns %r" % head)
    check(len(body) == len(ms), "headings rows %d" % len(body))
    check(all(r[3] in TRUST for r in body), "trust names %r" % sorted({r[3] for r in body}))
    g = [int(r[4]) for r in body]
    check(all(g[i] <= g[i + 1] for i in range(len(g) - 1)) and g[-1] == gen, "generation column")
    first = adopted[0] if adopted else len(body)
    check(all(r[3] in ("uncalibrated", "no_heading") for r in body[:first]), "trusted before the first adoption")
    trusted = sum(1 for r in body if r[3] == "ok")
    check(trusted == rep.get("trusted_rows") and trusted > 0, "trusted_rows %r vs CSV %d" % (rep.get("trusted_rows"), trusted))
    b = subprocess.run([a.exe, "--mode", "3d", "--json", dump], capture_output=True, text=True)
    check(b.returncode == 0, "batch 3d exit %d" % b.returncode)
    brep = json.loads(b.stdout)
    sb = spread(brep["matrix"], brep["offset"], ms)
    ss = spread(rep["matrix"], rep["offset"], ms)
    check(abs(ss - rep["bfield_spread_all_rows"]) < 1e-4, "bfield_spread_all_rows %r vs %r" % (rep["bfield_spread_all_rows"], ss))
    check(ss <= sb + 0.0005, "|B| spread stream %.4f %% > batch %.4f %% + 0.05 pp" % (100 * ss, 100 * sb))
    bad = subprocess.run([a.exe, "--stream", "--mode", "4d", dump], capture_output=True, text=True)
    check(bad.returncode == 1 and "--mode" in bad.stderr, "--mode 4d: exit %d" % bad.returncode)
    print("stream 3d %s: rows %d, trusted %d, adoptions %s, events %d, |B| spread stream %.4f %% batch %.4f %% (%+.4f pp)"
          % (os.path.basename(dump), len(ms), trusted, adopted, len(ev), 100 * ss, 100 * sb, 100 * (ss - sb)))
    return 1 if FAILS else 0


if __name__ == "__main__":
    sys.exit(main())
