#!/usr/bin/env python3
"""CTest checks of magcal-replay against known truth (python3 standard library only).

    check_replay.py --exe PATH --source-dir DIR --work-dir DIR [--python PY] CASE

Cases (one CTest test each):
  real_flat_turns  bundled LSM9DS1 dump: ok, radius spread drops >= 5x, centre/radius near the
                   importer's independent least-squares fit (tests/data/real/*.README.md)
  real_glitches    bundled dump with driver glitches: every glitch row flagged, few false alarms,
                   spread drop >= 5x, centre near the importer's fit of the clean rows
  synthetic_floor  every tests/data/synthetic/*.csv (tools/gen_dump.py, truth in *.json):
                   heading RMS on the verification rows <= factor x floor_deg, centre near truth,
                   pooled per-reference RMS consistent with the total (algorithms.md 9)
  malformed_csv    broken dumps: exit 2 and the exact FILE:LINE:COL message
  cal_failed       a 72-degree arc: exit 3, status "coverage", a reason, JSON still on stdout
  usage            bad command lines: exit 1
  plane_xz         the same turn stored in (mx, mz) and replayed with --plane XZ gives the same result
  decimation       2500 calibration rows (> capacity): deterministic every-k-th decimation reported
  headings_csv     --headings file: one row per input row, columns, errors consistent with the JSON
  plot             tools/plot_replay.py writes a PNG (exit 77 = skipped when matplotlib is missing)
  swing            mount_rot3 (gen_dump.py --extra): 3 deg mounting rotation; --ref-rows fits the
                   swing: before ~3 deg, after <= 1.2 x floor; fourier model too; SPREAD and
                   TOO_FEW_POINTS reported with exit 0
  tilt_3d          tilt_tumble (gen_dump3d.py): --mode 3d + tilt: heading RMS <= 1.2 x floor on
                   tilted rows, tilt gate counts equal the truth's
  tilt_2d          level_tilted (gen_dump3d.py): 2d calibration + tilt with --inclination: <= 1.2 x
                   floor; without it (vertical component 0) and without tilt: >= 5 x floor
  outliers_3d      tumble_outliers (gen_dump3d.py): --mode 3d outlier column = the fit's final gate:
                   every injected row flagged (calibration and verification), count over the
                   calibration rows = n_outliers, truth_flags, console outlier-row count
  burst_3d         tumble_burst (gen_dump3d.py): dense burst 80 % outside the shell + far spikes:
                   the 3-D OPTICS density stage rejects all 30, V and heading at truth; with
                   --filter none the fit's gate alone accepts the burst (V error > 5 uT)
  real_3d          bundled 3-D tumbles: corrected spread within 5 % of an independent numpy
                   ellipsoid fit (tools/ref_real_spread3d.py), drop factors, accelerometer unit
  aided            aided_road (gen_aided_dump.py): G, V near truth (test_aided.c tolerances),
                   converged, DOP gate count, WMM B_ref, heading RMS <= 1.2 x floor; headings CSV
                   outlier = the DOP-gated rows, gate column
  aided_prior      aided_level (gen_aided_dump.py --level, calibration exactly level): --prior
                   identity vs TRUE calibration (both unobservable; the true prior gives G, V and
                   tilted headings at truth), a report passed back as prior, unit conversion,
                   3d-report rescaling, bad prior files (exit 2)
  modes_usage      errors of the new options and columns (exit 1 / 2)
Exit status 0 = pass, 1 = fail (messages on stderr), 77 = skipped.
"""
import argparse
import csv
import json
import math
import os
import random
import subprocess
import sys

FAILS = []

# Heading RMS on the verification rows must stay within this factor of the noise floor
# (floor_deg in the truth JSON: the RMS the TRUE correction gives on the same noisy rows).
FLOOR_FACTOR = 1.2


def check(cond, msg):
    if not cond:
        FAILS.append(msg)
        sys.stderr.write("FAIL: %s\n" % msg)
    return cond


def run(a, args, expect_rc=None):
    p = subprocess.run([a.exe] + args, capture_output=True, text=True)
    if expect_rc is not None:
        check(p.returncode == expect_rc, "%s: exit %d, expected %d\nstderr: %s" % (
            " ".join(args), p.returncode, expect_rc, p.stderr.strip()))
    return p


def run_json(a, args, expect_rc=0):
    p = run(a, ["--json"] + args, expect_rc)
    try:
        return json.loads(p.stdout)
    except ValueError:
        check(False, "%s: stdout is not one JSON object: %r" % (" ".join(args), p.stdout[:300]))
        return {}


def real(a, name):
    return os.path.join(a.source_dir, "tests", "data", "real", name)


def synthetic_dir(a):
    return os.path.join(a.source_dir, "tests", "data", "synthetic")


def spread_drop(rep):
    return rep["radius_spread_raw_used"] / max(rep["radius_spread_corrected"], 1e-12)


def read_csv_rows(path):
    with open(path, newline="") as f:
        lines = [ln for ln in f if ln.strip() and not ln.lstrip().startswith("#")]
    return list(csv.DictReader(lines))


# --------------------------------------------------------------------------- cases

def case_real_flat_turns(a):
    rep = run_json(a, [real(a, "lsm9ds1_pmodnav_flat_turns.csv")])
    check(rep.get("status") == "ok", "status %r" % rep.get("status"))
    check(rep.get("n_rows") == 136 and rep.get("n_cal") == 136, "row counts %r" % rep)
    # Spread drop over the samples used. Measured 4.88x; an independent float64 least-squares
    # ellipse fit (numpy) of all 136 rows gives 4.89x: this hand-turned recording scatters 2.6 %
    # around its best ellipse, so no ellipse correction reaches the 5x first hoped for.
    check(spread_drop(rep) >= 4.5, "radius spread drop %.2fx < 4.5x" % spread_drop(rep))
    check(rep["radius_spread_raw_used"] == rep["radius_spread_raw"], "no outliers: both raw spreads equal")
    # importer's plain LS fit (README): centre (0.02456, 0.02832), semi-axes 0.2483 / 0.2188
    cx, cy = rep["center"]
    check(math.hypot(cx - 0.02456, cy - 0.02832) <= 0.01, "centre %r far from (0.02456, 0.02832)" % rep["center"])
    check(abs(rep["radius"] - math.sqrt(0.2483 * 0.2188)) <= 0.1 * 0.2331, "radius %g" % rep["radius"])
    check(rep["coverage_deg"] >= 330.0, "coverage %g" % rep["coverage_deg"])
    check("heading_rms_deg" not in rep, "no reference headings in this dump, yet heading metrics reported")


def case_real_glitches(a):
    hp = os.path.join(a.work_dir, "glitches_headings.csv")
    rep = run_json(a, ["--headings", hp, real(a, "lsm9ds1_pmodnav_driver_glitches.csv")])
    check(rep.get("status") == "ok", "status %r reason %r" % (rep.get("status"), rep.get("reason")))
    t = rep.get("truth_flags", {})
    check(t.get("column") == "glitch" and t.get("flagged") == 71, "truth flags %r (README: 71 glitches)" % t)
    check(t.get("missed") == 0, "glitch rows not flagged: %r" % t)
    check(t.get("false_alarms", 999) <= 0.10 * (303 - 71), "false alarms %r > 10%% of clean rows" % t)
    check(rep["n_outliers"] >= 71, "n_outliers %r < 71 glitches" % rep["n_outliers"])
    # Over the samples used: measured 3.77x (an independent float64 LS fit of the 232 clean rows:
    # 2.5x). Over every calibration sample the glitches (y = -8.9 gauss) dominate the raw spread.
    check(spread_drop(rep) >= 3.5, "radius spread drop %.2fx < 3.5x" % spread_drop(rep))
    drop_all = rep["radius_spread_raw"] / rep["radius_spread_corrected"]
    check(drop_all >= 5.0, "spread drop incl. glitches %.2fx < 5x" % drop_all)
    cx, cy = rep["center"]
    check(math.hypot(cx - 0.01954, cy - 0.03711) <= 0.01, "centre %r far from (0.01954, 0.03711)" % rep["center"])
    dump = read_csv_rows(real(a, "lsm9ds1_pmodnav_driver_glitches.csv"))
    rows = read_csv_rows(hp)
    check(len(rows) == len(dump) == 303, "headings rows %d, dump rows %d" % (len(rows), len(dump)))
    for i, (d, h) in enumerate(zip(dump, rows)):
        if d["glitch"] == "1":
            check(h["outlier"] == "1", "glitch row %d not flagged in the headings CSV" % i)


def case_synthetic_floor(a):
    sd = synthetic_dir(a)
    names = sorted(f[:-5] for f in os.listdir(sd) if f.endswith(".json"))
    check(len(names) >= 5, "too few synthetic dumps in %s" % sd)
    for nm in names:
        with open(os.path.join(sd, nm + ".json")) as f:
            truth = json.load(f)
        n_cal = truth["n_cal"]
        rep = run_json(a, ["--cal-range", "0:%d" % n_cal, os.path.join(sd, nm + ".csv")])
        if not check(rep.get("status") == "ok", "%s: status %r (%r)" % (nm, rep.get("status"), rep.get("reason"))):
            continue
        factor = FLOOR_FACTOR
        rms, floor = rep["heading_rms_deg"], truth["floor_deg"]
        sys.stdout.write("%-18s heading RMS %.4f deg, floor %.4f deg, ratio %.3f (limit %.2f); "
                         "outliers %d/%d; spread drop %.1fx\n" % (
                             nm, rms, floor, rms / floor, factor, rep["n_outliers"], truth["n_outliers"],
                             spread_drop(rep)))
        check(rms <= factor * floor, "%s: heading RMS %.4f > %.2f x floor %.4f" % (nm, rms, factor, floor))
        check(rep["n_heading"] == truth["n_rows"] - n_cal, "%s: n_heading %r" % (nm, rep["n_heading"]))
        # centre within 1% of the radius of the true hard iron
        bx, by = truth["b"]
        cx, cy = rep["center"]
        check(math.hypot(cx - bx, cy - by) <= 0.01 * truth["radius_mean"],
              "%s: centre %r vs truth %r" % (nm, rep["center"], truth["b"]))
        # per-reference table: the 8 verification headings, pooled RMS = total RMS (alg. 9)
        groups = rep["heading_rms_by_ref"]
        check([g["ref_deg"] for g in groups] == truth["verification"]["headings_deg"],
              "%s: reference groups %r" % (nm, [g["ref_deg"] for g in groups]))
        pooled = math.sqrt(sum(g["n"] * g["rms_deg"] ** 2 for g in groups) / sum(g["n"] for g in groups))
        check(abs(pooled - rms) <= 1e-4 * max(1.0, rms), "%s: pooled %.6f != total %.6f" % (nm, pooled, rms))


MALFORMED = [
    # (file name, content, extra args, expected exit, expected stderr fragment)
    ("bad_number.csv", "t,mx,my\n0,1,2\n0.1,1,1.2.3\n", [], 2,
     "bad_number.csv:3:3: expected a number, got \"1.2.3\" (column my)"),
    ("no_my.csv", "# header below\nt,mx,mz\n0,1,2\n", [], 2,
     "no_my.csv:2: missing required column \"my\" in the header"),
    ("truncated.csv", "t,mx,my,mz\n0,1,2,3\n0.1,1", [], 2,
     "truncated.csv:3:3: row has 2 fields but the header has 4 (truncated line?)"),
    ("empty.csv", "", [], 2, "empty.csv: no header row (empty file, or only comments)"),
    ("header_only.csv", "mx,my\r\n", [], 2, "header_only.csv: no data rows after the header"),
    ("missing_cell.csv", "mx,my\n1,2\n3,\n", [], 2,
     "missing_cell.csv:3:2: column \"my\" is required, got an empty cell"),
    ("long_line.csv", "mx,my\n1," + "9" * 100000 + "\n", [], 2,
     "long_line.csv:2:2: number longer than 63 characters in column \"my\""),
    ("binary.csv", "mx,my\n1\x002,3\n", [], 2, "binary.csv:2: NUL byte in the line (binary file?)"),
]


def case_malformed_csv(a):
    for name, content, extra, rc, msg in MALFORMED:
        path = os.path.join(a.work_dir, name)
        with open(path, "w", newline="") as f:
            f.write(content)
        p = run(a, extra + [path], rc)
        check(msg in p.stderr, "%s: stderr %r lacks %r" % (name, p.stderr.strip(), msg))
        check(p.stdout == "", "%s: stdout not empty on an input error" % name)
    p = run(a, [os.path.join(a.work_dir, "does_not_exist.csv")], 2)
    check("does_not_exist.csv: cannot open: No such file or directory" in p.stderr, "missing file: %r" % p.stderr)
    # a 2-axis dump replayed in a plane that needs mz: the nan cell is reported, not used
    p = run(a, ["--plane", "XZ", real(a, "lsm9ds1_pmodnav_flat_turns.csv")], 2)
    check("lsm9ds1_pmodnav_flat_turns.csv:2:4: column \"mz\" is required, got \"nan\"" in p.stderr,
          "plane XZ on a 2-axis dump: %r" % p.stderr)
    p = run(a, ["--cal-range", "100:200", real(a, "lsm9ds1_pmodnav_flat_turns.csv")], 2)
    check("--cal-range 100:200 is empty or beyond the dump's 136 rows" in p.stderr, "cal-range: %r" % p.stderr)


def case_cal_failed(a):
    path = os.path.join(synthetic_dir(a), "clean.csv")
    # 60 of 600 rows over 720 degrees: a 72-degree arc, far below the 270-degree coverage gate
    p = run(a, ["--json", "--cal-range", "0:60", path], 3)
    try:
        rep = json.loads(p.stdout)
    except ValueError:
        check(False, "no JSON on stdout for a failed calibration: %r" % p.stdout)
        return
    check(rep.get("status") == "coverage", "status %r, expected coverage" % rep.get("status"))
    check(rep.get("status_code") == -7, "status_code %r" % rep.get("status_code"))
    check(len(rep.get("reason", "")) > 10, "no reason: %r" % rep.get("reason"))
    check("center" not in rep and "heading_rms_deg" not in rep, "geometry reported for a failed run")
    check("calibration failed" in p.stderr, "stderr: %r" % p.stderr)
    p = run(a, ["--cal-range", "0:60", path], 3)
    check("status            coverage" in p.stdout, "table: %r" % p.stdout)


def case_usage(a):
    dump = real(a, "lsm9ds1_pmodnav_flat_turns.csv")
    for args in ([], ["--filter", "kmeans", dump], ["--plane", "XX", dump], ["--eps", "-1", dump],
                 ["--min-pts", "x", dump], ["--bogus", dump], [dump, dump], ["--declination", "200", dump],
                 ["--cal-range", dump], ["--filter", "none", "--eps", "0.1", dump]):
        p = run(a, args, 1)
        check("usage: magcal-replay" in p.stderr, "%r: no usage text" % args)
    p = run(a, ["--help"], 0)
    check("--cal-range" in p.stdout, "--help text")
    # a malformed range is a usage error (exit 1, before the dump is read); one that does not fit
    # the dump is an input error (exit 2)
    p = run(a, ["--cal-range", "5", dump], 1)
    check("--cal-range must be A:B" in p.stderr, "cal-range syntax: %r" % p.stderr)
    p = run(a, ["--cal-range", "0:5000", dump], 2)
    check("beyond the dump" in p.stderr, "cal-range beyond the dump: %r" % p.stderr)


def case_plane_xz(a):
    src = os.path.join(synthetic_dir(a), "outliers_10.csv")
    rows = read_csv_rows(src)
    path = os.path.join(a.work_dir, "outliers_10_xz.csv")
    with open(path, "w") as f:
        f.write("t,mx,my,mz,heading_ref_deg\n")
        for r in rows:
            f.write("%s,%s,nan,%s,%s\n" % (r["t"], r["mx"], r["my"], r["heading_ref_deg"]))
    ref = run_json(a, ["--cal-range", "0:600", src])
    xz = run_json(a, ["--cal-range", "0:600", "--plane", "XZ", path])
    for k in ("status", "center", "correction", "radius", "n_outliers", "heading_rms_deg"):
        check(ref.get(k) == xz.get(k), "plane XZ: %s %r != XY %r" % (k, xz.get(k), ref.get(k)))
    # mirrored pair: heading runs backwards, calibration geometry is the same size
    zx = run_json(a, ["--cal-range", "0:600", "--plane", "ZX", path])
    check(abs(zx.get("radius", 0) - ref.get("radius", 1)) <= 1e-3 * ref.get("radius", 1), "plane ZX radius")
    check(zx.get("heading_rms_deg", 0) > 10.0, "plane ZX should mirror the heading sense")


def case_decimation(a):
    # A clean ring of 2500 calibration rows (10 turns) + 80 verification rows, known truth.
    rng = random.Random(7)
    h0, bx, by, sigma = 30.0, -5.0, 9.0, 0.1
    t = [[1.2, 0.1], [0.1, 0.9]]
    n_cal, lines = 2500, ["t,mx,my,heading_ref_deg"]
    refs = []
    for i in range(n_cal + 80):
        psi = (3600.0 * i / n_cal) % 360.0 if i < n_cal else 45.0 * ((i - n_cal) // 10)
        hx, hy = -h0 * math.sin(math.radians(psi)), h0 * math.cos(math.radians(psi))
        mx = t[0][0] * hx + t[0][1] * hy + bx + rng.gauss(0, sigma)
        my = t[1][0] * hx + t[1][1] * hy + by + rng.gauss(0, sigma)
        lines.append("%.2f,%.6f,%.6f,%.4f" % (0.05 * i, mx, my, psi))
        refs.append(psi)
    path = os.path.join(a.work_dir, "ring_2500.csv")
    with open(path, "w") as f:
        f.write("\n".join(lines) + "\n")
    rep = run_json(a, ["--cal-range", "0:%d" % n_cal, path])
    cap = rep.get("capacity", 0)
    k = -(-n_cal // cap) if cap else 0
    check(cap >= 16 and rep.get("decimation") == k, "decimation %r for capacity %r" % (rep.get("decimation"), cap))
    check(rep.get("n_fed") == -(-n_cal // k) if k else False, "n_fed %r" % rep.get("n_fed"))
    check(rep.get("status") == "ok", "status %r" % rep.get("status"))
    check(math.hypot(rep["center"][0] - bx, rep["center"][1] - by) <= 0.05, "centre %r" % rep.get("center"))
    check(rep.get("heading_rms_deg", 99) <= 0.5, "heading RMS %r" % rep.get("heading_rms_deg"))
    p = run(a, ["--cal-range", "0:%d" % n_cal, path], 0)
    check("every %d-th fed" % k in p.stdout, "table does not state the decimation: %r" % p.stdout)


def case_headings_csv(a):
    src = os.path.join(synthetic_dir(a), "outliers_10.csv")
    hp = os.path.join(a.work_dir, "outliers_10_headings.csv")
    rep = run_json(a, ["--cal-range", "0:600", "--declination", "-3.5", "--headings", hp, src])
    with open(hp) as f:
        header = f.readline().strip()
    check(header == "index,raw_heading_deg,heading_deg,outlier,heading_ref_deg,error_deg", "header %r" % header)
    rows = read_csv_rows(hp)
    check(len(rows) == rep.get("n_rows") == 680, "rows %d vs n_rows %r" % (len(rows), rep.get("n_rows")))
    errs = []
    for i, r in enumerate(rows):
        check(int(r["index"]) == i, "index column")
        h, ref, e = float(r["heading_deg"]), float(r["heading_ref_deg"]), float(r["error_deg"])
        check(0.0 <= h < 360.0, "heading %g out of [0,360)" % h)
        d = (h - ref + 180.0) % 360.0 - 180.0
        check(abs(d - e) < 2e-3 or abs(abs(d - e) - 360.0) < 2e-3, "row %d: error %g != wrap(%g - %g)" % (i, e, h, ref))
        if i >= 600:
            errs.append(e)
    # declination -3.5 shifts every heading: the error is about -3.5 deg (truth has none)
    rms = math.sqrt(sum(x * x for x in errs) / len(errs))
    check(abs(rms - rep["heading_rms_deg"]) <= 2e-3, "RMS from CSV %.4f vs JSON %.4f" % (rms, rep["heading_rms_deg"]))
    check(abs(rep["heading_bias_deg"] + 3.5) <= 0.2, "declination not applied: bias %r" % rep["heading_bias_deg"])
    # without a reference column the two optional columns are absent
    hp2 = os.path.join(a.work_dir, "flat_headings.csv")
    run(a, ["--headings", hp2, real(a, "lsm9ds1_pmodnav_flat_turns.csv")], 0)
    with open(hp2) as f:
        check(f.readline().strip() == "index,raw_heading_deg,heading_deg,outlier", "header without reference")
    p = run(a, ["--headings", os.path.join(a.work_dir, "no_such_dir", "h.csv"), src], 4)
    check("cannot write" in p.stderr, "unwritable headings file: %r" % p.stderr)


def case_plot(a):
    py = a.python or sys.executable
    probe = subprocess.run([py, "-c", "import matplotlib"], capture_output=True)
    if probe.returncode != 0:
        sys.stderr.write("skipped: %s has no matplotlib\n" % py)
        return 77
    dump = real(a, "lsm9ds1_pmodnav_driver_glitches.csv")
    hp = os.path.join(a.work_dir, "plot_headings.csv")
    jp = os.path.join(a.work_dir, "plot_report.json")
    png = os.path.join(a.work_dir, "plot.png")
    p = run(a, ["--json", "--headings", hp, dump], 0)
    with open(jp, "w") as f:
        f.write(p.stdout)
    script = os.path.join(a.source_dir, "tools", "plot_replay.py")
    q = subprocess.run([py, script, dump, "--headings", hp, "--report", jp, "-o", png],
                       capture_output=True, text=True)
    check(q.returncode == 0, "plot_replay.py exit %d: %s" % (q.returncode, q.stderr))
    with open(png, "rb") as f:
        head = f.read(8)
    check(head == b"\x89PNG\r\n\x1a\n", "not a PNG")
    check(os.path.getsize(png) > 20000, "PNG suspiciously small")
    return 0


def extra_data(a, name):
    return os.path.join(a.source_dir, "tools", "replay", "tests", "data", name)


def load_truth(a, name):
    with open(extra_data(a, name + ".json")) as f:
        return json.load(f)


def case_swing(a):
    truth = load_truth(a, "mount_rot3")
    path = extra_data(a, "mount_rot3.csv")
    n_cal = truth["n_cal"]
    r0, r1 = truth["reference"]["rows"]
    floor = truth["floor_deg"]
    # without the swing the 3 deg mounting rotation stays (the ellipse cannot see a rotation)
    plain = run_json(a, ["--cal-range", "0:%d" % n_cal, path])
    check("swing" not in plain and "heading_rms_deg_before_swing" not in plain, "swing fields without --ref-rows")
    check(abs(plain.get("heading_bias_deg", 0) - truth["rot_deg"]) <= 0.3,
          "plain bias %r, expected ~%g" % (plain.get("heading_bias_deg"), truth["rot_deg"]))
    rep = run_json(a, ["--cal-range", "0:%d" % n_cal, "--ref-rows", "%d:%d" % (r0, r1), path])
    sw = rep.get("swing", {})
    sys.stdout.write("swing: before %.4f deg, after %.4f deg, floor %.4f deg (ratio %.3f); A..E %r\n" % (
        rep.get("heading_rms_deg_before_swing", -1), rep.get("heading_rms_deg", -1), floor,
        rep.get("heading_rms_deg", 99) / floor, sw.get("coefficients_deg")))
    check(sw.get("status") == "ok" and sw.get("model") == "smith", "swing %r" % sw)
    check(sw.get("method") == "bins" and sw.get("n_points") == 8 and sw.get("n_ref") == r1 - r0,
          "8 reference headings x 20 rows must be binned: %r" % sw)
    check(abs(rep.get("heading_rms_deg_before_swing", 0) - 3.0) <= 0.3, "before swing %r" % rep.get("heading_rms_deg_before_swing"))
    check(rep.get("heading_rms_deg", 99) <= FLOOR_FACTOR * floor, "after swing %r > %.2f x floor %.4f" % (
        rep.get("heading_rms_deg"), FLOOR_FACTOR, floor))
    # verification rows only: the 16 headings between the reference ones
    check(rep.get("n_heading") == truth["n_rows"] - r1 and rep.get("n_heading_before_swing") == truth["n_rows"] - r1,
          "verification rows %r" % rep.get("n_heading"))
    check([g["ref_deg"] for g in rep.get("heading_rms_by_ref", [])] == truth["verification"]["headings_deg"],
          "per-ref table after swing")
    coef = sw.get("coefficients_deg", [0] * 5)
    check(abs(coef[0] + truth["rot_deg"]) <= 0.15 and all(abs(c) <= 0.15 for c in coef[1:]),
          "A..E %r: expected (-%g, 0, 0, 0, 0) +- 0.15" % (coef, truth["rot_deg"]))
    # the adaptive Fourier model on the same rows
    fo = run_json(a, ["--cal-range", "0:%d" % n_cal, "--ref-rows", "%d:%d" % (r0, r1), "--swing-model", "fourier", path])
    check(fo.get("swing", {}).get("status") == "ok" and fo["swing"].get("model") == "fourier", "fourier %r" % fo.get("swing"))
    check(fo.get("heading_rms_deg", 99) <= FLOOR_FACTOR * floor, "fourier after %r" % fo.get("heading_rms_deg"))
    # headings CSV carries the heading before the swing
    hp = os.path.join(a.work_dir, "swing_headings.csv")
    run(a, ["--cal-range", "0:%d" % n_cal, "--ref-rows", "%d:%d" % (r0, r1), "--headings", hp, path], 0)
    rows = read_csv_rows(hp)
    check("heading_before_swing_deg" in rows[0], "headings CSV lacks heading_before_swing_deg")
    # reference rows at 3 headings (0, 45, 90): SPREAD (min pivot ~0); 3 rows: TOO_FEW_POINTS. Exit 0.
    for ref_rows, status in (("%d:%d" % (r0, r0 + 60), "too_few_points"), ("%d:%d" % (r0, r0 + 3), "too_few_points")):
        bad = run_json(a, ["--cal-range", "0:%d" % n_cal, "--ref-rows", ref_rows, path], 0)
        check(bad.get("status") == "ok" and bad.get("swing", {}).get("status") == status,
              "ref rows %s: swing %r, expected %s" % (ref_rows, bad.get("swing"), status))
        check("coefficients_deg" not in bad.get("swing", {}), "coefficients of a failed swing")
        check(bad.get("heading_rms_deg") == bad.get("heading_rms_deg_before_swing"),
              "failed swing: heading_rms_deg must be the unswung value")
    # five distinct headings on one half circle, one row each (pairs): the spread test refuses
    lines = ["t,mx,my,heading_ref_deg"]
    src = read_csv_rows(path)
    for i, r in enumerate(src[:n_cal]):
        lines.append("%s,%s,%s,nan" % (r["t"], r["mx"], r["my"]))
    for k, psi in enumerate((0.0, 30.0, 60.0, 90.0, 120.0, 150.0)):
        # the calibration rows nearest psi give a plausible compass heading
        j = min(range(n_cal), key=lambda i: abs(((float(src[i]["heading_ref_deg"]) - psi) + 180) % 360 - 180))
        lines.append("%d,%s,%s,%.1f" % (1000 + k, src[j]["mx"], src[j]["my"], psi))
    hp2 = os.path.join(a.work_dir, "half_circle_refs.csv")
    with open(hp2, "w") as f:
        f.write("\n".join(lines) + "\n")
    bad = run_json(a, ["--cal-range", "0:%d" % n_cal, "--ref-rows", "%d:%d" % (n_cal, n_cal + 6), hp2], 0)
    check(bad.get("swing", {}).get("status") == "spread" and bad["swing"].get("method") == "pairs",
          "half-circle references: swing %r, expected spread" % bad.get("swing"))


def case_tilt_3d(a):
    truth = load_truth(a, "tilt_tumble")
    path = extra_data(a, "tilt_tumble.csv")
    rep = run_json(a, ["--mode", "3d", "--cal-range", "0:%d" % truth["n_cal"], path])
    check(rep.get("status") == "ok" and rep.get("mode") == "3d", "status %r" % rep.get("status"))
    check(rep.get("model") == "quadric9" and rep.get("coverage", 0) >= 0.9, "model %r coverage %r" % (
        rep.get("model"), rep.get("coverage")))
    t = rep.get("tilt", {})
    check(t.get("accel_unit") == "g" and t.get("accel_unit_source") == "detected", "accel unit %r" % t)
    want = {k: truth["gates"].get(k, 0) for k in ("ok", "free_fall", "accel_norm", "gimbal", "zero_field")}
    got = {k: t.get("gates", {}).get(k) for k in want}
    check(got == want, "tilt gates %r, truth %r" % (got, want))
    floor = truth["floor_deg"]
    v0, v1 = truth["verification"]["rows"]
    sys.stdout.write("tilt_3d: heading RMS %.4f deg, floor %.4f deg (ratio %.3f), gates %r\n" % (
        rep.get("heading_rms_deg", -1), floor, rep.get("heading_rms_deg", 99) / floor, got))
    check(rep.get("n_heading") == v1 - v0, "n_heading %r: the 7 gated rows have no heading" % rep.get("n_heading"))
    check(rep.get("heading_rms_deg", 99) <= FLOOR_FACTOR * floor, "heading RMS %r > %.2f x floor %.4f" % (
        rep.get("heading_rms_deg"), FLOOR_FACTOR, floor))
    # offset: the ellipsoid's V is the true V
    check(math.dist(rep.get("offset", [0, 0, 0]), truth["V"]) <= 0.01 * truth["F"], "offset %r vs %r" % (
        rep.get("offset"), truth["V"]))
    # --no-tilt: level headings of tilted rows are far off
    nt = run_json(a, ["--mode", "3d", "--no-tilt", "--cal-range", "0:%d" % truth["n_cal"], path])
    check("tilt" not in nt and nt.get("heading_rms_deg", 0) > 5 * floor, "--no-tilt: %r" % nt.get("heading_rms_deg"))
    # explicit unit overrides detection (m/s^2 would make |a| ~ 0.1 g: every row free fall)
    mp = run_json(a, ["--mode", "3d", "--accel-unit", "mps2", "--cal-range", "0:%d" % truth["n_cal"], path])
    check(mp.get("tilt", {}).get("accel_unit_source") == "given" and
          mp.get("tilt", {}).get("gates", {}).get("free_fall") == truth["n_rows"], "--accel-unit mps2: %r" % mp.get("tilt"))


def case_burst_3d(a):
    """3d mode: a dense burst 80 % outside the shell + 10 far spikes. The OPTICS density stage
    (default --filter optics) takes them out; the fit's residual gate alone (--filter none)
    accepts the burst as a compromise fit."""
    truth = load_truth(a, "tumble_burst")
    path = extra_data(a, "tumble_burst.csv")
    n_cal = truth["n_cal"]
    base = ["--mode", "3d", "--cal-range", "0:%d" % n_cal, path]
    rep = run_json(a, base)
    off = run_json(a, ["--filter", "none"] + base)
    dn, tf = rep.get("density", {}), rep.get("truth_flags", {})
    verr = math.dist(rep.get("offset", [0, 0, 0]), truth["V"])
    verr_off = math.dist(off.get("offset", [0, 0, 0]), truth["V"])
    sys.stdout.write("burst_3d: density stage %r, residual gate %r, truth %r, V error %.3f uT, heading RMS %.4f deg "
                     "(floor %.4f); --filter none: V error %.3f uT, heading RMS %.3f deg, truth %r\n" % (
                         dn, rep.get("n_residual_rejected"), tf, verr, rep.get("heading_rms_deg", -1),
                         truth["floor_deg"], verr_off, off.get("heading_rms_deg", -1), off.get("truth_flags")))
    check(rep.get("status") == "ok" and rep.get("filter") == "optics", "status %r filter %r" % (
        rep.get("status"), rep.get("filter")))
    # measured: the density stage rejects exactly the 30 injected rows, the gate 2 more
    check(dn.get("rejected", 0) >= 30 and dn.get("eps_prime", 0) > 0 and dn.get("min_pts") == 4, "density %r" % dn)
    check(tf.get("flagged") == 30 and tf.get("detected") == 30 and tf.get("missed") == 0, "truth flags %r" % tf)
    check(tf.get("false_alarms", 99) <= 3, "false alarms %r" % tf.get("false_alarms"))
    check(rep.get("n_outliers") == dn.get("rejected", 0) + rep.get("n_residual_rejected", 0), "n_outliers %r" % rep.get("n_outliers"))
    check(verr < 0.1, "V error %.3f uT >= 0.1 (measured 0.019)" % verr)
    check(rep.get("heading_rms_deg", 99) <= FLOOR_FACTOR * truth["floor_deg"], "heading RMS %r" % rep.get("heading_rms_deg"))
    # without the density stage the burst drags the fit (measured V error 12 uT, heading RMS 52 deg)
    check(off.get("density", {}).get("rejected") == 0 and off.get("filter") == "none", "filter none: %r" % off.get("density"))
    check(verr_off > 5.0 and off.get("truth_flags", {}).get("missed", 0) >= 20, "filter none: V error %.3f, truth %r" % (
        verr_off, off.get("truth_flags")))
    # the 2-D-only DBSCAN filter is refused in 3d mode
    run(a, ["--filter", "dbscan"] + base, 1)


def case_outliers_3d(a):
    truth = load_truth(a, "tumble_outliers")
    path = extra_data(a, "tumble_outliers.csv")
    n_cal = truth["n_cal"]
    hp = os.path.join(a.work_dir, "tumble_outliers_headings.csv")
    rep = run_json(a, ["--mode", "3d", "--cal-range", "0:%d" % n_cal, "--headings", hp, path])
    check(rep.get("status") == "ok" and rep.get("model") == "quadric9", "status %r model %r" % (
        rep.get("status"), rep.get("model")))
    rows = read_csv_rows(hp)
    check(len(rows) == truth["n_rows"], "headings rows %d" % len(rows))
    flagged = [int(r["index"]) for r in rows if r["outlier"] == "1"]
    truth_rows = set(truth["outlier_rows"])
    cal_flagged = [i for i in flagged if i < n_cal]
    ver_extra = [i for i in flagged if i >= n_cal and i not in truth_rows]
    tf = rep.get("truth_flags", {})
    sys.stdout.write("outliers_3d: %d rows flagged (%d calibration, n_outliers %r), truth %d (%d calibration); "
                     "truth_flags %r; verification false alarms %r; heading RMS %.4f deg, floor %.4f deg\n" % (
                         len(flagged), len(cal_flagged), rep.get("n_outliers"), len(truth_rows),
                         truth["n_cal_outliers"], tf, ver_extra, rep.get("heading_rms_deg", -1), truth["floor_deg"]))
    # every injected outlier row flagged, in the calibration AND the verification rows
    check(truth_rows <= set(flagged), "missed outlier rows %r" % sorted(truth_rows - set(flagged)))
    # calibration rows: the CSV mask is the fit's own (its count is n_outliers = n_cal - n_used)
    check(len(cal_flagged) == rep.get("n_outliers") == n_cal - rep.get("n_used", 0),
          "calibration rows flagged %d vs n_outliers %r" % (len(cal_flagged), rep.get("n_outliers")))
    check(rep.get("n_outlier_rows") == len(flagged), "n_outlier_rows %r vs CSV %d" % (rep.get("n_outlier_rows"), len(flagged)))
    # truth flags over the fed (calibration) rows; measured 24 / 24, 0 missed, 1 false alarm
    check(tf.get("column") == "outlier" and tf.get("flagged") == truth["n_cal_outliers"] and
          tf.get("detected") == truth["n_cal_outliers"] and tf.get("missed") == 0, "truth_flags %r" % tf)
    check(tf.get("false_alarms", 99) <= 3, "false alarms %r > 3 (3-sigma gate, 600 rows)" % tf.get("false_alarms"))
    check(tf.get("detected", 0) + tf.get("false_alarms", 0) == rep.get("n_outliers"), "detected + false alarms != n_outliers")
    check(len(ver_extra) <= 5, "verification false alarms %r > 5 (measured 3 of 160)" % ver_extra)
    check(rep.get("n_heading_flagged") == sum(1 for i in flagged if i >= n_cal), "n_heading_flagged %r" % rep.get("n_heading_flagged"))
    # radial errors leave the heading unchanged: heading RMS stays at the floor
    check(rep.get("heading_rms_deg", 99) <= FLOOR_FACTOR * truth["floor_deg"], "heading RMS %r" % rep.get("heading_rms_deg"))
    # the table names the count
    p = run(a, ["--mode", "3d", "--cal-range", "0:%d" % n_cal, path], 0)
    check("outlier rows      %d of %d rows" % (len(flagged), truth["n_rows"]) in p.stdout, "table: %r" % p.stdout[:600])
    check("truth flags       %d fed rows have outlier=1" % truth["n_cal_outliers"] in p.stdout, "table truth line")
    # a dump without truth column: no truth_flags, and no outliers on a clean tumble
    clean = run_json(a, ["--mode", "3d", "--cal-range", "0:600", extra_data(a, "tilt_tumble.csv")])
    check("truth_flags" not in clean and clean.get("n_outliers") == 0 and clean.get("n_outlier_rows") == 0,
          "clean tumble: %r" % {k: clean.get(k) for k in ("n_outliers", "n_outlier_rows", "truth_flags")})


def case_tilt_2d(a):
    truth = load_truth(a, "level_tilted")
    path = extra_data(a, "level_tilted.csv")
    floor = truth["floor_deg"]
    base = ["--cal-range", "0:%d" % truth["n_cal"], path]
    rep = run_json(a, ["--inclination", str(truth["inclination_deg"])] + base)
    t = rep.get("tilt", {})
    check(rep.get("status") == "ok" and t.get("gates", {}).get("ok") == truth["n_rows"], "tilt %r" % t)
    # level vertical component: -H tan I (radius = H here: det T = 1)
    hz = -truth["h_horizontal"] * math.tan(math.radians(truth["inclination_deg"]))
    check(abs(t.get("hz_level", 0) - hz) <= 0.01 * abs(hz), "hz_level %r vs %g" % (t.get("hz_level"), hz))
    # z_offset = mean mz over the level turn = V_z + vertical field
    check(abs(t.get("z_offset", 0) - (truth["V"][2] + hz)) <= 0.05, "z_offset %r vs %g" % (t.get("z_offset"), truth["V"][2] + hz))
    no_inc = run_json(a, base)
    p = run(a, base, 0)
    check("without --inclination" in p.stderr, "no note on stderr about the missing inclination: %r" % p.stderr)
    no_tilt = run_json(a, ["--no-tilt"] + base)
    sys.stdout.write("tilt_2d: with --inclination %.4f deg, without %.4f deg, no tilt %.4f deg, floor %.4f deg\n" % (
        rep.get("heading_rms_deg", -1), no_inc.get("heading_rms_deg", -1), no_tilt.get("heading_rms_deg", -1), floor))
    check(rep.get("heading_rms_deg", 99) <= FLOOR_FACTOR * floor, "2d+tilt %r > %.2f x floor" % (rep.get("heading_rms_deg"), FLOOR_FACTOR))
    check(no_inc.get("heading_rms_deg", 0) >= 5 * floor, "without --inclination the vertical component is missing")
    check(no_tilt.get("heading_rms_deg", 0) >= 5 * floor, "without tilt compensation tilted rows are off")


# independent numpy ellipsoid fit of every row (tools/ref_real_spread3d.py), measured 2026-11-22;
# used when no numpy is available to recompute it
REAL_3D = {
    # name: (rows, accel unit, numpy raw spread, numpy corrected spread, min drop)
    "lsm9ds1_pmodnav_tumble": (534, "mps2", 0.30559, 0.06189, 4.5),
    "ellipsoid_fit_python_sample": (347, None, 0.36770, 0.02059, 15.0),
}


def case_real_3d(a):
    py = a.python or sys.executable
    have_np = subprocess.run([py, "-c", "import numpy"], capture_output=True).returncode == 0
    for name, (rows, unit, raw_ref, cor_ref, min_drop) in sorted(REAL_3D.items()):
        path = real(a, name + ".csv")
        if have_np:
            q = subprocess.run([py, os.path.join(a.source_dir, "tools", "ref_real_spread3d.py"), path, "--json"],
                               capture_output=True, text=True)
            ref = json.loads(q.stdout)
            check(abs(ref["spread_corrected"] - cor_ref) <= 1e-4, "%s: numpy reference moved: %r" % (name, ref))
            raw_ref, cor_ref = ref["spread_raw"], ref["spread_corrected"]
        rep = run_json(a, ["--mode", "3d", path])
        check(rep.get("status") == "ok" and rep.get("n_rows") == rows, "%s: status %r" % (name, rep.get("status")))
        check(rep.get("model") == "quadric9", "%s: model %r" % (name, rep.get("model")))
        raw, cor = rep.get("radius_spread_raw", 0), rep.get("radius_spread_corrected", 1)
        sys.stdout.write("%s: spread raw %.4f -> corrected %.4f (%.1fx); numpy LS %.4f -> %.4f (%.1fx)\n" % (
            name, raw, cor, raw / cor, raw_ref, cor_ref, raw_ref / cor_ref))
        check(abs(raw - raw_ref) <= 1e-4, "%s: raw spread %r vs %r" % (name, raw, raw_ref))
        check(cor <= 1.05 * cor_ref, "%s: corrected spread %.5f > 1.05 x numpy %.5f" % (name, cor, cor_ref))
        check(raw / cor >= min_drop, "%s: drop %.2fx < %.1fx" % (name, raw / cor, min_drop))
        if unit is None:
            check("tilt" not in rep, "%s: no accelerometer, no tilt" % name)
        else:
            check(rep.get("tilt", {}).get("accel_unit") == unit, "%s: accel unit %r" % (name, rep.get("tilt")))
            check(sum(rep["tilt"]["gates"].values()) == rows, "%s: gate counts cover every row" % name)


def case_aided(a):
    truth = load_truth(a, "aided_road")
    path = extra_data(a, "aided_road.csv")
    rep = run_json(a, ["--mode", "aided", "--cal-range", "0:%d" % truth["n_cal"], path])
    ad = rep.get("aided", {})
    check(rep.get("status") == "ok" and ad.get("status") == "ok", "status %r aided %r" % (rep.get("status"), ad))
    b = ad.get("b_ref_ned_first", [0, 0, 0])
    check(math.dist(b, truth["b_ref_ned_uT"]) <= 1e-3, "B_ref %r vs WMM CLI %r" % (b, truth["b_ref_ned_uT"]))
    check(abs(ad.get("declination_first_deg", 0) - truth["declination_deg"]) <= 1e-3, "declination %r" % ad)
    check(ad.get("gated", {}).get("dop") == truth["dop_gated"], "DOP gated %r, expected %d" % (ad.get("gated"), truth["dop_gated"]))
    check(ad.get("n_accepted") == truth["n_cal"] - truth["dop_gated"], "accepted %r" % ad.get("n_accepted"))
    check(0 < ad.get("converged_at", -1) < truth["n_cal"] and ad.get("converged_row", -1) >= ad.get("converged_at", 0),
          "convergence %r / row %r" % (ad.get("converged_at"), ad.get("converged_row")))
    check(ad.get("n_prior_dirs") == 0, "prior directions %r" % ad.get("n_prior_dirs"))
    # tests/test_aided.c tolerances at 1 deg RMS tilt: relative G error < 2 %, |V error| < 1.5 uT
    G, Gt = rep.get("matrix", [[0] * 3] * 3), truth["G_true"]
    num = sum((G[i][j] - Gt[i][j]) ** 2 for i in range(3) for j in range(3))
    den = sum(Gt[i][j] ** 2 for i in range(3) for j in range(3))
    gerr, verr = math.sqrt(num / den), math.dist(rep.get("offset", [0, 0, 0]), truth["V"])
    floor = truth["floor_deg"]
    sys.stdout.write("aided: G error %.4f, V error %.3f uT, converged at %r (row %r), heading RMS %.4f deg, "
                     "floor %.4f deg (ratio %.3f)\n" % (gerr, verr, ad.get("converged_at"), ad.get("converged_row"),
                                                         rep.get("heading_rms_deg", -1), floor,
                                                         rep.get("heading_rms_deg", 99) / floor))
    check(gerr < 0.02, "G relative error %.4f >= 0.02" % gerr)
    check(verr < 1.5, "V error %.3f uT >= 1.5" % verr)
    check(rep.get("n_heading") == truth["n_rows"] - truth["n_cal"], "n_heading %r" % rep.get("n_heading"))
    check(rep.get("heading_rms_deg", 99) <= FLOOR_FACTOR * floor, "heading RMS %r > %.2f x floor %.4f" % (
        rep.get("heading_rms_deg"), FLOOR_FACTOR, floor))
    # headings CSV: outlier = epochs gated by magcal_aided_update, gate column names the gate
    hp = os.path.join(a.work_dir, "aided_road_headings.csv")
    run(a, ["--mode", "aided", "--cal-range", "0:%d" % truth["n_cal"], "--headings", hp, path], 0)
    with open(hp) as f:
        header = f.readline().strip()
    check(header == "index,raw_heading_deg,heading_deg,outlier,heading_ref_deg,error_deg,gate", "aided header %r" % header)
    hrows = read_csv_rows(hp)
    out_rows = [int(r["index"]) for r in hrows if r["outlier"] == "1"]
    check(out_rows == list(range(500, 550)), "outlier rows %r: expected the DOP rows 500-549" % out_rows[:60])
    gates = {}
    for r in hrows:
        gates.setdefault(r["gate"], []).append(int(r["index"]))
    check(sorted(gates) == ["", "dop", "none"] and gates["dop"] == out_rows and len(gates["none"]) == ad.get("n_accepted")
          and gates[""] == list(range(truth["n_cal"], truth["n_rows"])),
          "gate column: %r" % {k: len(v) for k, v in gates.items()})
    check(rep.get("n_outlier_rows") == 50 and ad.get("prior") == "identity", "n_outlier_rows %r prior %r" % (
        rep.get("n_outlier_rows"), ad.get("prior")))
    # objective: combined by default (total-field residual in the objective for nearly every
    # accepted epoch after the first estimate); --aided-objective vector: none, same accuracy class
    check(ad.get("objective") == "combined" and ad.get("n_total_field", 0) > 0.9 * ad.get("n_accepted", 0),
          "objective %r, total-field epochs %r of %r" % (ad.get("objective"), ad.get("n_total_field"), ad.get("n_accepted")))
    check(0.0 < ad.get("resid_f_rms", -1) < 0.1, "a-priori total-field residual RMS %r uT (noise 0.05)" % ad.get("resid_f_rms"))
    vrep = run_json(a, ["--mode", "aided", "--aided-objective", "vector", "--cal-range", "0:%d" % truth["n_cal"], path])
    vad = vrep.get("aided", {})
    vg = g_rel_err(vrep.get("matrix", [[0] * 3] * 3), Gt)
    vv = math.dist(vrep.get("offset", [0, 0, 0]), truth["V"])
    sys.stdout.write("aided --aided-objective vector: G error %.4f, V error %.3f uT\n" % (vg, vv))
    check(vad.get("objective") == "vector" and vad.get("n_total_field") == 0, "vector run: %r" % vad)
    check(vg < 0.02 and vv < 1.5, "vector objective: G %.4f, V %.3f" % (vg, vv))
    run(a, ["--mode", "2d", "--aided-objective", "vector", path], 1)
    # --model igrf14: the same site from IGRF-14 (WMM and IGRF agree to ~0.1 uT here), same accuracy class
    irep = run_json(a, ["--mode", "aided", "--model", "igrf14", "--cal-range", "0:%d" % truth["n_cal"], path])
    iad = irep.get("aided", {})
    db = math.dist(iad.get("b_ref_ned_first", [0, 0, 0]), truth["b_ref_ned_uT"])
    check(iad.get("model") == "IGRF-14" and ad.get("model") == "WMM2025", "model names %r %r" % (iad.get("model"), ad.get("model")))
    check(0.0 < db < 0.3, "IGRF-14 vs WMM2025 B_ref differ by %.3f uT" % db)
    check(irep.get("status") == "ok" and g_rel_err(irep.get("matrix", [[0] * 3] * 3), Gt) < 0.02,
          "igrf14 run: status %r" % irep.get("status"))
    run(a, ["--mode", "2d", "--model", "igrf14", path], 1)
    # the same rows with the INS level (roll = pitch = 0 for all): no excitation of z -> unobservable
    rows = read_csv_rows(path)
    lvl = os.path.join(a.work_dir, "aided_level.csv")
    with open(lvl, "w") as f:
        cols = list(rows[0].keys())
        f.write(",".join(cols) + "\n")
        for r in rows[:truth["n_cal"]]:
            f.write(",".join(("0" if c in ("roll_deg", "pitch_deg") else r[c]) for c in cols) + "\n")
    lv = run_json(a, ["--mode", "aided", lvl], 0)
    check(lv.get("aided", {}).get("status") in ("unobservable", "not_converged"),
          "attitude-inconsistent level drive: %r" % lv.get("aided", {}).get("status"))
    # too few epochs: no estimate, exit 3
    short = run_json(a, ["--mode", "aided", "--cal-range", "0:20", path], 3)
    check(short.get("status") == "too_few_points", "20 epochs: status %r" % short.get("status"))


def g_rel_err(G, Gt):
    num = sum((G[i][j] - Gt[i][j]) ** 2 for i in range(3) for j in range(3))
    den = sum(Gt[i][j] ** 2 for i in range(3) for j in range(3))
    return math.sqrt(num / den)


def case_aided_prior(a):
    truth = load_truth(a, "aided_level")
    path = extra_data(a, "aided_level.csv")
    base = ["--mode", "aided", "--cal-range", "0:%d" % truth["n_cal"], path]
    floor = truth["floor_deg"]

    def write(name, obj):
        p = os.path.join(a.work_dir, name)
        with open(p, "w") as f:
            f.write(obj if isinstance(obj, str) else json.dumps(obj))
        return p

    def summary(rep):
        return (g_rel_err(rep.get("matrix", [[0] * 3] * 3), truth["G_true"]),
                math.dist(rep.get("offset", [0, 0, 0]), truth["V"]), rep.get("heading_rms_deg", 99))

    ident = run_json(a, base)
    true_p = write("prior_true.json", {"matrix": truth["G_true"], "offset": truth["V"]})
    tp = run_json(a, ["--prior", true_p] + base)
    gi, vi, hi = summary(ident)
    gt, vt, ht = summary(tp)
    sys.stdout.write("aided_prior: identity prior: %s, G error %.4f, V error %.3f uT, tilted heading RMS %.4f deg; "
                     "true prior: %s, G error %.5f, V error %.4f uT, heading RMS %.4f deg; floor %.4f deg\n" % (
                         ident.get("status"), gi, vi, hi, tp.get("status"), gt, vt, ht, floor))
    # exactly level calibration: unobservable either way (the prior fills the z terms)
    check(ident.get("status") == "unobservable" and tp.get("status") == "unobservable",
          "status identity %r, true prior %r" % (ident.get("status"), tp.get("status")))
    check(ident.get("aided", {}).get("prior") == "identity" and tp.get("aided", {}).get("prior") == true_p,
          "prior names %r / %r" % (ident.get("aided", {}).get("prior"), tp.get("aided", {}).get("prior")))
    check(ident.get("aided", {}).get("n_prior_dirs", 0) >= 1 and tp.get("aided", {}).get("n_prior_dirs", 0) >= 1,
          "directions from the prior: %r / %r" % (ident.get("aided"), tp.get("aided")))
    # measured: identity G error 0.1446, V error 9.65 uT, heading 0.781 deg (floor 0.139);
    # true prior: G error 1e-4, V error 0.001 uT, heading 0.139 deg
    check(gi > 0.10 and vi > 5.0 and hi > 4.0 * floor, "identity prior should be visibly wrong at tilt: %r" % ((gi, vi, hi),))
    check(gt < 0.002 and vt < 0.05, "true prior: G error %.5f >= 0.002 or V error %.4f >= 0.05 uT" % (gt, vt))
    check(ht <= FLOOR_FACTOR * floor, "true prior: heading RMS %.4f > %.2f x floor %.4f" % (ht, FLOOR_FACTOR, floor))
    # the JSON report of that run passed back as the prior: same result (report round trip)
    rp = write("prior_report.json", json.dumps(tp))
    back = run_json(a, ["--prior", rp] + base)
    gb, vb, hb = summary(back)
    check(gb < 0.002 and vb < 0.05 and hb <= FLOOR_FACTOR * floor, "report as prior: %r" % ((gb, vb, hb),))
    # the prior's unit: V in nT with "field_unit": "nT" is converted to the dump's uT
    nt = write("prior_nt.json", {"matrix": truth["G_true"], "offset": [1000.0 * x for x in truth["V"]], "field_unit": "nT"})
    gn, vn, hn = summary(run_json(a, ["--prior", nt] + base))
    check(abs(gn - gt) < 1e-4 and abs(vn - vt) < 1e-3, "nT prior: %r vs %r" % ((gn, vn), (gt, vt)))
    # a 3d report maps to its own F (det G = 1): rescaled by |B_ref| / F
    fb = math.sqrt(sum(x * x for x in truth["b_ref_ned_uT"]))
    three = write("prior_3d.json", {"mode": "3d", "matrix": [[g * 50.0 / fb for g in row] for row in truth["G_true"]],
                                    "offset": truth["V"], "field": 50.0})
    r3 = run_json(a, ["--prior", three] + base)
    g3, v3, _ = summary(r3)
    check(abs(r3.get("aided", {}).get("prior_g_scale", 0) - fb / 50.0) < 1e-5 and g3 < 0.002,
          "3d report prior: scale %r, G error %.5f" % (r3.get("aided", {}).get("prior_g_scale"), g3))
    # bad prior files: exit 2, message names the file
    bad = {
        "prior_missing.json": None,
        "prior_notjson.json": "{\"matrix\": [[1, 0, 0],",
        "prior_nooffset.json": {"matrix": [[1, 0, 0], [0, 1, 0], [0, 0, 1]]},
        "prior_shape.json": {"matrix": [[1, 0, 0], [0, 1, 0]], "offset": [0, 0, 0]},
        "prior_string.json": {"matrix": [[1, 0, 0], [0, "1", 0], [0, 0, 1]], "offset": [0, 0, 0]},
        "prior_singular.json": {"matrix": [[1, 2, 3], [2, 4, 6], [0, 0, 1]], "offset": [0, 0, 0]},
        "prior_unit.json": {"matrix": [[1, 0, 0], [0, 1, 0], [0, 0, 1]], "offset": [0, 0, 0], "field_unit": "mG"},
    }
    want = {"prior_missing.json": "cannot open the prior", "prior_notjson.json": "is not a JSON object",
            "prior_nooffset.json": "no \"offset\" key", "prior_shape.json": "3 rows of 3 finite numbers",
            "prior_string.json": "3 rows of 3 finite numbers", "prior_singular.json": "is singular",
            "prior_unit.json": "\"field_unit\" must be"}
    for name, obj in sorted(bad.items()):
        p = os.path.join(a.work_dir, name) if obj is None else write(name, obj)
        if obj is None and os.path.exists(p):
            os.remove(p)
        q = run(a, ["--prior", p] + base, 2)
        check(p in q.stderr and want[name] in q.stderr, "%s: stderr %r" % (name, q.stderr))
    # --prior outside the aided mode: usage error
    q = run(a, ["--mode", "3d", "--prior", true_p, path], 1)
    check("--prior is for the aided mode" in q.stderr, "--prior with 3d: %r" % q.stderr)


def case_modes_usage(a):
    dump = real(a, "lsm9ds1_pmodnav_flat_turns.csv")
    for args in (["--mode", "4d", dump], ["--swing-model", "poly", dump], ["--accel-unit", "furlong", dump],
                 ["--inclination", "95", dump], ["--mode", "3d", "--inclination", "60", dump],
                 ["--field-unit", "tesla", dump], ["--year", "x", dump], ["--mode", "aided", "--tilt", dump]):
        p = run(a, args, 1)
        check("usage: magcal-replay" in p.stderr, "%r: no usage text" % args)
    # input errors (exit 2)
    p = run(a, ["--mode", "3d", dump], 2)
    check("column \"mz\" is required" in p.stderr, "3d on a 2-axis dump: %r" % p.stderr)
    p = run(a, ["--ref-rows", "0:10", dump], 2)
    check("--ref-rows needs a heading_ref_deg column" in p.stderr, "ref rows without reference: %r" % p.stderr)
    p = run(a, ["--ref-rows", "10:5", dump], 2)
    check("--ref-rows 10:5 is empty" in p.stderr, "ref rows range: %r" % p.stderr)
    p = run(a, ["--tilt", real(a, "ellipsoid_fit_python_sample.csv")], 2)
    check("--tilt needs the columns ax, ay, az" in p.stderr, "--tilt without accel: %r" % p.stderr)
    p = run(a, ["--mode", "aided", real(a, "lsm9ds1_pmodnav_tumble.csv")], 2)
    check("missing required column \"roll_deg\"" in p.stderr, "aided without INS: %r" % p.stderr)
    # accelerometer unit that cannot be told (|a| ~ 3)
    path = os.path.join(a.work_dir, "odd_accel.csv")
    with open(path, "w") as f:
        f.write("mx,my,mz,ax,ay,az\n")
        for i in range(40):
            ang = math.radians(9 * i)
            f.write("%.4f,%.4f,-30,0,0,3\n" % (-20 * math.sin(ang), 20 * math.cos(ang)))
    p = run(a, [path], 2)
    check("cannot tell the accelerometer unit" in p.stderr, "odd accel: %r" % p.stderr)
    # aided epoch source: t is not a Unix time and no decimal_year
    rows = read_csv_rows(extra_data(a, "aided_road.csv"))
    path = os.path.join(a.work_dir, "aided_no_year.csv")
    with open(path, "w") as f:
        cols = [c for c in rows[0].keys() if c != "decimal_year"]
        f.write(",".join(cols) + "\n")
        for r in rows[:100]:
            f.write(",".join(r[c] for c in cols) + "\n")
    p = run(a, ["--mode", "aided", path], 2)
    check("is not a Unix time" in p.stderr, "aided without an epoch: %r" % p.stderr)
    rep = run_json(a, ["--mode", "aided", "--year", "2026.5", path], 0)
    check(rep.get("aided", {}).get("n_seen") == 100, "--year: %r" % rep.get("aided"))
    p = run(a, ["--mode", "aided", "--year", "2031", path], 2)
    check("outside WMM2025 validity" in p.stderr, "--year 2031: %r" % p.stderr)


CASES = {n[5:]: f for n, f in globals().items() if n.startswith("case_")}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--exe", required=True)
    ap.add_argument("--source-dir", required=True)
    ap.add_argument("--work-dir", required=True)
    ap.add_argument("--python")
    ap.add_argument("case", choices=sorted(CASES))
    a = ap.parse_args()
    os.makedirs(a.work_dir, exist_ok=True)
    rc = CASES[a.case](a)
    if rc == 77:
        return 77
    if FAILS:
        sys.stderr.write("%d check(s) failed in case %s\n" % (len(FAILS), a.case))
        return 1
    print("case %s: all checks passed" % a.case)
    return 0


if __name__ == "__main__":
    sys.exit(main())
