#!/usr/bin/env python3
"""CTest check of `magcal-replay --export-record` (python3 standard library only).

    check_record.py --exe PATH --source-dir DIR --work-dir DIR

The exported bytes are decoded here with an implementation independent of src/record.c
(struct '<' little-endian + zlib.crc32, layout of include/magcal/record.h) and compared with the
JSON report of the same replay: 2-D (bundled LSM9DS1 glitch dump) and 3-D (bundled tumble), a
failed calibration exports nothing (exit 3), a bad --sensor-id is a usage error (exit 1).
Exit status 0 = pass, 1 = fail.
"""
import argparse
import json
import math
import os
import struct
import subprocess
import sys
import zlib

FAILS = []
STAMP = 1764547200


def check(cond, msg):
    if not cond:
        FAILS.append(msg)
        sys.stderr.write("FAIL: %s\n" % msg)
    return cond


def run(a, args):
    env = dict(os.environ, SOURCE_DATE_EPOCH=str(STAMP))
    return subprocess.run([a.exe] + args, capture_output=True, text=True, env=env)


def decode(path):
    with open(path, "rb") as f:
        b = f.read()
    check(len(b) == 96, "%s: %d bytes, expected 96" % (path, len(b)))
    (magic, ver, ln, kind, unit, res, sensor, created, n, est, radius, resid, cov) = struct.unpack_from(
        "<IHHBBHIIIffff", b, 0)
    cal = struct.unpack_from("<13f", b, 40)
    (crc,) = struct.unpack_from("<I", b, 92)
    check(crc == zlib.crc32(b[:92]) & 0xFFFFFFFF, "%s: CRC-32 does not match zlib's" % path)
    check(magic == 0x4452434D and b[:4] == b"MCRD" and ver == 1 and ln == 96 and res == 0,
          "%s: header %x %d %d %d" % (path, magic, ver, ln, res))
    return dict(kind=kind, unit=unit, sensor=sensor, created=created, n=n, est=est, radius=radius,
                resid=resid, cov=cov, cal=cal)


def close(x, y, rel=2e-6, abs_=1e-9):
    return abs(x - y) <= rel * abs(y) + abs_


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--exe", required=True)
    ap.add_argument("--source-dir", required=True)
    ap.add_argument("--work-dir", required=True)
    a = ap.parse_args()
    os.makedirs(a.work_dir, exist_ok=True)
    real = os.path.join(a.source_dir, "tests", "data", "real")

    # ---- 2-D: the README's demo dump
    out2 = os.path.join(a.work_dir, "glitches.rec")
    dump2 = os.path.join(real, "lsm9ds1_pmodnav_driver_glitches.csv")
    p = run(a, ["--json", "--export-record", out2, "--sensor-id", "0x1E", dump2])
    check(p.returncode == 0, "2d export: exit %d: %s" % (p.returncode, p.stderr))
    rep = json.loads(p.stdout)
    r = decode(out2)
    check(r["kind"] == 2 and r["unit"] == 0 and r["sensor"] == 0x1E and r["created"] == STAMP,
          "2d fields %r" % r)
    check(r["n"] == rep["n_used"] and r["cov"] == rep["coverage_deg"], "2d n/coverage %r vs %r" % (r, rep))
    check(close(r["radius"], rep["radius"]) and close(r["resid"], rep["residual_rms"]), "2d radius/residual %r" % r)
    check(math.isfinite(r["est"]) and 0.0 < r["est"] < 5.0, "2d heading-error estimate %r" % r["est"])
    c = r["cal"]
    check(close(c[0], rep["center"][0]) and close(c[1], rep["center"][1]), "2d offset %r vs %r" % (c[:2], rep["center"]))
    m = rep["correction"]
    check(all(close(c[2 + 2 * i + j], m[i][j]) for i in range(2) for j in range(2)), "2d M %r vs %r" % (c[2:6], m))
    check(close(c[6], rep["radius"]) and all(v == 0.0 for v in c[7:]), "2d cal radius / zero tail %r" % (c,))
    sys.stdout.write("2d record: sensor 0x%X, n %d, radius %.6g, est. heading error %.3f deg\n" % (
        r["sensor"], r["n"], r["radius"], r["est"]))

    # ---- 3-D: bundled tumble
    out3 = os.path.join(a.work_dir, "tumble.rec")
    p = run(a, ["--json", "--mode", "3d", "--export-record", out3, os.path.join(real, "lsm9ds1_pmodnav_tumble.csv")])
    check(p.returncode == 0, "3d export: exit %d: %s" % (p.returncode, p.stderr))
    rep = json.loads(p.stdout)
    r = decode(out3)
    check(r["kind"] == 3 and r["sensor"] == 0 and math.isnan(r["est"]), "3d fields %r" % r)
    c = r["cal"]
    g = rep["matrix"]
    check(all(close(c[3 * i + j], g[i][j]) for i in range(3) for j in range(3)), "3d G %r vs %r" % (c[:9], g))
    check(all(close(c[9 + i], rep["offset"][i]) for i in range(3)), "3d V %r vs %r" % (c[9:12], rep["offset"]))
    check(close(c[12], rep["field"]) and close(r["radius"], rep["field"]), "3d field %r vs %r" % (c[12], rep["field"]))
    check(close(r["cov"], rep["coverage"]) and r["n"] == rep["n_used"], "3d coverage/n %r" % r)

    # ---- stream mode: --save writes the calibration in force at the end, --install starts from it
    flat = os.path.join(real, "lsm9ds1_pmodnav_flat_turns.csv")
    saved = os.path.join(a.work_dir, "stream.rec")
    p = run(a, ["--stream", "--json", "--save", saved, flat])
    check(p.returncode == 0, "stream --save: exit %d: %s" % (p.returncode, p.stderr))
    rep = json.loads(p.stdout)
    r = decode(saved)
    c = r["cal"]
    check(r["kind"] == 2 and rep["generation"] >= 1, "stream record kind %r, generation %r" % (r["kind"], rep["generation"]))
    check(close(c[0], rep["offset"][0]) and close(c[1], rep["offset"][1]) and close(c[6], rep["radius"]),
          "stream record offset / radius %r vs %r %r" % (c[:2], rep["offset"], rep["radius"]))
    m = rep["matrix"]
    check(all(close(c[2 + 2 * i + j], m[i][j]) for i in range(2) for j in range(2)), "stream record M %r vs %r" % (c[2:6], m))
    heads = os.path.join(a.work_dir, "stream_installed.csv")
    p = run(a, ["--stream", "--json", "--install", saved, "--headings", heads, flat])
    check(p.returncode == 0, "stream --install: exit %d: %s" % (p.returncode, p.stderr))
    with open(heads) as f:
        first = f.read().splitlines()[1].split(",")
    # the restored calibration is in force from the first row (generation 0: no adoption yet)
    check(first[3] != "uncalibrated" and first[4] == "0" and first[1] != first[2],
          "first row under --install: %r" % (first,))
    bad = os.path.join(a.work_dir, "stream_corrupt.rec")
    with open(saved, "rb") as f:
        b = bytearray(f.read())
    b[50] ^= 1
    with open(bad, "wb") as f:
        f.write(b)
    p = run(a, ["--stream", "--install", bad, flat])
    check(p.returncode == 1 and "--install" in p.stderr, "corrupt --install: exit %d %r" % (p.returncode, p.stderr))
    sys.stdout.write("stream record: generation %d, radius %.6g; --install: first row %s\n" % (
        rep["generation"], r["radius"], first[3]))

    # ---- a failed calibration exports nothing; a bad sensor id is a usage error
    bad = os.path.join(a.work_dir, "failed.rec")
    if os.path.exists(bad):
        os.remove(bad)
    p = run(a, ["--cal-range", "0:60", "--export-record", bad,
                os.path.join(a.source_dir, "tests", "data", "synthetic", "clean.csv")])
    check(p.returncode == 3 and not os.path.exists(bad), "failed calibration: exit %d, file %s" % (
        p.returncode, os.path.exists(bad)))
    p = run(a, ["--export-record", bad, "--sensor-id", "-3", dump2])
    check(p.returncode == 1 and "--sensor-id" in p.stderr, "bad --sensor-id: exit %d %r" % (p.returncode, p.stderr))
    return 1 if FAILS else 0


if __name__ == "__main__":
    sys.exit(main())
