#!/usr/bin/env python3
"""Build the libFuzzer seed corpora from the dumps (standard library only).

  make_corpus.py --source-dir REPO --out DIR [--shared-dir /work/shared]

Writes DIR/replay_csv/, DIR/calibrator/, DIR/cluster/, DIR/3d/, DIR/cont/ (one file per seed, named by content hash).
Inputs: REPO/tests/data/{real,synthetic}/*.csv, SHARED/data/real/*/data.csv when given, and the
committed seeds in tools/fuzz/seeds/<harness>/ (hand-written CSVs, reproducers of fixed crashes). The corpora are build products: never commit them.

Seed formats are those documented at the top of fuzz_calibrator.c, fuzz_cluster.c, fuzz_3d.c and fuzz_cont.c.
"""
import argparse
import glob
import hashlib
import math
import os
import random
import shutil
import struct

CSV_HEAD_LINES = 40      # csv seeds: header + up to this many data lines (keeps seeds < ~4 kB)
MAX_POINTS = 1024        # MAGCAL_MAX_SAMPLES
PTS_PER_SEED = (60, 300)      # points per binary seed (capacity up to 1024 is fuzzed anyway)


def write_seed(d, data):
    os.makedirs(d, exist_ok=True)
    name = hashlib.sha1(data).hexdigest()
    with open(os.path.join(d, name), "wb") as f:
        f.write(data)


def read_xy(path):
    """(x, y) pairs of the mx, my columns; rows with a missing/non-numeric cell are skipped."""
    pts = []
    header = None
    with open(path, "r", encoding="utf-8", errors="replace") as f:
        for line in f:
            s = line.strip()
            if not s or s.startswith("#"):
                continue
            cells = [c.strip().strip('"').lower() for c in s.split(",")]
            if header is None:
                header = cells
                if "mx" not in header or "my" not in header:
                    return []
                ix, iy = header.index("mx"), header.index("my")
                continue
            try:
                x, y = float(cells[ix]), float(cells[iy])
            except (ValueError, IndexError):
                continue
            if math.isfinite(x) and math.isfinite(y):
                pts.append((x, y))
    return pts


def csv_seeds(path, out):
    with open(path, "rb") as f:
        lines = f.read().splitlines(keepends=True)
    # first non-comment line is the header; keep leading comments (they are part of the format)
    k = 0
    while k < len(lines) and (lines[k].strip() == b"" or lines[k].lstrip().startswith(b"#")):
        k += 1
    head = lines[: k + 1]
    body = lines[k + 1:]
    step = max(1, len(body) // CSV_HEAD_LINES)
    write_seed(out, b"".join(head + body[:CSV_HEAD_LINES]))
    write_seed(out, b"".join(head + body[::step][:CSV_HEAD_LINES]))


def subsample(pts, m):
    if len(pts) <= m:
        return pts
    step = len(pts) / m
    return [pts[int(i * step)] for i in range(m)]


def int16_scaled(pts):
    big = max(max(abs(x), abs(y)) for x, y in pts) or 1.0
    scale = big / 16000.0
    q = b"".join(struct.pack("<hh", int(round(x / scale)), int(round(y / scale))) for x, y in pts)
    return scale, q


def f32(pts):
    return b"".join(struct.pack("<ff", x, y) for x, y in pts)


def calibrator_seeds(pts, out):
    for m in PTS_PER_SEED:
        p = subsample(pts, m)
        if len(p) < 20:
            continue
        cap = min(MAX_POINTS, len(p))
        scale, q = int16_scaled(p)
        for filt in (0, 2):                             # OPTICS grid, DBSCAN (others by mutation)
            mode = filt | 0x04                          # consensus on
            hdr = struct.pack("<BHBBfBf", mode, cap - 16, 0, 0, 0.0, 0, 0.0)
            write_seed(out, hdr + f32(p))
            hdr = struct.pack("<BHBBfBf", mode | 0x80 | 0x20, cap - 16, 0, 0, 0.0, 0, scale)
            write_seed(out, hdr + q)
        # plain fit, gated push, previous calibration usable
        write_seed(out, struct.pack("<BHBBfBf", 0x20, cap - 16, 0x32, 0, 0.0, 0, 0.0) + f32(p))


def cluster_seeds(pts, out):
    for m in PTS_PER_SEED:
        p = subsample(pts, m)
        if len(p) < 8:
            continue
        xs = [a for a, _ in p]
        ys = [b for _, b in p]
        span = max(max(xs) - min(xs), max(ys) - min(ys)) or 1.0
        eps = span * 0.05
        scale, q = int16_scaled(p)
        for flags in (0x05, 0x00):                      # improved+grid, classic+brute
            write_seed(out, struct.pack("<ffBBf", eps, eps * 0.8, 4, flags, 0.0) + f32(p))
        write_seed(out, struct.pack("<ffBBf", eps / scale * scale, eps, 6, 0x15, scale) + q)


def seeds_3d(out):
    """fuzz_3d.c synthetic drives: flags, W - I, V, then (yaw step, pitch, roll, 3 noise, dop) per
    epoch. Road-like turning with ~1 deg tilt, level, and one with a high-DOP segment; both
    objectives, forgetting and noise compensation."""
    rng = random.Random(2026)
    for flags, tilt, n in ((0x00, 20, 1300), (0x01, 20, 1300), (0x06, 20, 1300), (0x04, 0, 1000),
                           (0x10, 60, 1300), (0x20, 40, 1200)):
        hdr = bytes([flags]) + bytes((rng.randrange(-40, 41) & 0xFF) for _ in range(9)) + \
            bytes((rng.randrange(-60, 61) & 0xFF) for _ in range(3))
        body = bytearray()
        for k in range(n):
            step = 30 if (k % 75) >= 60 else rng.randrange(0, 3)
            dop = 200 if 500 <= k < 520 else 48
            body += bytes([step, rng.randrange(-tilt, tilt + 1) & 0xFF, rng.randrange(-tilt, tilt + 1) & 0xFF,
                           rng.randrange(-10, 11) & 0xFF, rng.randrange(-10, 11) & 0xFF,
                           rng.randrange(-10, 11) & 0xFF, dop])
        write_seed(out, hdr + bytes(body))
    # raw epochs: one plausible, level, float layout
    raw = bytearray([0x40])
    for k in range(60):
        yaw = 0.2 * k
        raw += struct.pack("<10f", 20.0 * math.sin(yaw), 20.0 * math.cos(yaw), -44.0, 0.0, 0.0, yaw,
                           20.0, 1.2, 44.0, 1.2)
    write_seed(out, bytes(raw))


def read_xyz(path):
    """(x, y, z) of the mx, my, mz columns (z = 0 without mz); rows with a bad cell are skipped."""
    pts = []
    header = None
    with open(path, "r", encoding="utf-8", errors="replace") as f:
        for line in f:
            s = line.strip()
            if not s or s.startswith("#"):
                continue
            cells = [c.strip().strip('"').lower() for c in s.split(",")]
            if header is None:
                header = cells
                if "mx" not in header or "my" not in header:
                    return []
                ix, iy = header.index("mx"), header.index("my")
                iz = header.index("mz") if "mz" in header else None
                continue
            try:
                p = (float(cells[ix]), float(cells[iy]), float(cells[iz]) if iz is not None else 0.0)
            except (ValueError, IndexError):
                continue
            if all(math.isfinite(v) for v in p):
                pts.append(p)
    return pts


# fuzz_cont.c header at MAGCAL_CONT_CFG_DEFAULT (36 x 8, sweep 8, spacing 0.02, recentre 0.05,
# coverage 270, min_new 24, drain 2, age 600 s, k 4, rel 0.06, change 8 s over 3 bins, clear 4 s)
CONT_HDR = "<BBHBBBfHBBHBBHBHf"


def cont_header(flags, rng=0.0, drain=1, scale=0.0):
    return struct.pack(CONT_HDR, flags, 7, 28, 7, 10, 12, rng, 270, 24, drain, 6000, 60, 30, 2000, 2, 1000, scale)


def cont_ops(pts, dt_ms, every_heading=5, extra=b""):
    """push + step per sample (what a firmware does), a heading every few rows, progress at the end."""
    body = bytearray()
    for k, (x, y, z) in enumerate(pts):
        body += struct.pack("<BHfff", 0, dt_ms, x, y, z) + bytes([5])
        if k % every_heading == 0:
            body += bytes([6]) + struct.pack("<ffff", x, y, z, 2.5)
    return bytes(body) + extra + bytes([7])


def cont_seeds(dumps, out):
    """Stream seeds: each dump (up to 400 rows), and a synthetic ring with a glitch in row 0, a
    transient and every other op (solve_blocking, re-init, trust, the standalone store)."""
    for path in dumps:
        pts = read_xyz(path)
        if len(pts) >= 40:
            p = subsample(pts, 400) if len(pts) > 400 else pts
            write_seed(out, cont_header(0x10) + cont_ops(p, 20))
    rng = random.Random(13)
    ring = [(350.0, -420.0, 510.0)]
    for k in range(720):
        a = 2.0 * math.pi * k / 240.0
        f = 1.3 if 400 <= k < 420 else 1.0
        ring.append((120.0 + f * 48.0 * math.cos(a) + rng.gauss(0, 0.3), -40.0 + f * 39.0 * math.sin(a) +
                     rng.gauss(0, 0.3), 30.0 + rng.gauss(0, 0.3)))
    tail = bytes([8, 1]) + bytes([10]) + struct.pack("<fffffB", 60.0, -10.0, 0.02, 1.0, 60.0, 1) + \
        bytes([11, 2]) + struct.pack("<fff", 120.0, -40.0, 50.0) + bytes([11, 1]) + \
        struct.pack("<fff", 120.0, -40.0, 50.0) + bytes([9, 1]) + bytes([6]) + struct.pack("<ffff", 168.0, -40.0, 30.0, 0.0)
    write_seed(out, cont_header(0x19, rng=800.0) + cont_ops(ring, 20, 7, tail))
    write_seed(out, cont_header(0x15, drain=0) + cont_ops(ring[:400], 10, 11, tail))
def seeds_cont3(out):
    """fuzz_cont3.c: synthetic tumbles (the harness's V = (20, -10, 30), B = (0, 20, -40)) long
    enough to reach solves and adoptions: per sample a push op with its angle steps (x 0.05 rad),
    noise and a 20 ms time step, then a step op; a heading and a progress op now and then. One at
    the default configuration, one with short change / clear times, one with a calibration
    restored from flash (identity G, the true V)."""
    rng = random.Random(33)
    for flags, n in ((0x00, 1000), (0x10, 1000), (0x20, 900)):
        hdr = bytes([flags])
        if flags & 0x10:
            hdr += bytes([40, 20])                       # change_ms 400, clear_ms 200
        if flags & 0x20:
            hdr += struct.pack("<9f3ff", 1, 0, 0, 0, 1, 0, 0, 0, 1, 20.0, -10.0, 30.0, 44.72)
        body = bytearray()
        prev = [0, 0, 0]                                 # integer angle state (x 0.05 rad)
        for k in range(n):
            t = 0.02 * k
            want = [round((2.5 * t) / 0.05), round((1.3 * math.sin(1.1 * t)) / 0.05),
                    round((2.8 * math.sin(0.83 * t)) / 0.05)]
            steps = [max(-127, min(127, w - p)) for w, p in zip(want, prev)]
            prev = [p + d for p, d in zip(prev, steps)]
            body += bytes([0]) + bytes(d & 0xFF for d in steps) + \
                bytes(rng.randrange(-15, 16) & 0xFF for _ in range(3)) + bytes([20, 4])
            if k % 50 == 49:
                body += bytes([5 | (8 if k % 100 == 99 else 0), 30, 10, 0xF0])
            if k % 200 == 199:
                body += bytes([7])
        write_seed(out, hdr + bytes(body))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--source-dir", required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--shared-dir")
    a = ap.parse_args()

    dumps = sorted(glob.glob(os.path.join(a.source_dir, "tests/data/real/*.csv")) +
                   glob.glob(os.path.join(a.source_dir, "tests/data/synthetic/*.csv")))
    if a.shared_dir:
        dumps += sorted(glob.glob(os.path.join(a.shared_dir, "data/real/*/data.csv")))
    seeds = os.path.join(os.path.dirname(os.path.abspath(__file__)), "seeds")

    out_csv = os.path.join(a.out, "replay_csv")
    out_cal = os.path.join(a.out, "calibrator")
    out_clu = os.path.join(a.out, "cluster")
    out_3d = os.path.join(a.out, "3d")
    out_cont = os.path.join(a.out, "cont")
    out_c3 = os.path.join(a.out, "cont3")
    for d in (out_csv, out_cal, out_clu, out_3d, out_cont, out_c3):
        shutil.rmtree(d, ignore_errors=True)       # regenerated from scratch every time
        os.makedirs(d)
    # committed seeds: hand-written CSVs and the reproducers of fixed crashes (regressions)
    for harness, out in (("replay_csv", out_csv), ("calibrator", out_cal), ("cluster", out_clu), ("3d", out_3d),
                         ("cont", out_cont)):
        for h in sorted(glob.glob(os.path.join(seeds, harness, "*"))):
            with open(h, "rb") as f:
                write_seed(out, f.read())
    for path in dumps:
        csv_seeds(path, out_csv)
        pts = read_xy(path)
        if len(pts) >= 20:
            calibrator_seeds(pts, out_cal)
            cluster_seeds(pts, out_clu)
    seeds_3d(out_3d)
    cont_seeds(dumps, out_cont)
    seeds_cont3(out_c3)
    for d in (out_csv, out_cal, out_clu, out_3d, out_cont, out_c3):
        print("%s: %d seeds" % (d, len(os.listdir(d))))


if __name__ == "__main__":
    main()
