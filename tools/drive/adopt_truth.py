#!/usr/bin/python3
"""Score the continuous 2-D calibrator's solves on a generated drive against its truth.

    /usr/bin/python3 tools/drive/adopt_truth.py DRIVE.csv DRIVE.json ADOPT.jsonl
    /usr/bin/python3 tools/drive/adopt_truth.py --all DRIVE.csv DRIVE.json ADOPT.jsonl

--all: one line per solve ATTEMPT (adopted or not): row, cumulative turning at that row, status,
coverage, arc stage (1: an ellipse below the 270-deg gate), the arc bound, the noise estimate, and the candidate calibration's TRUE whole-circle heading error at level over 360
headings (the truth's G and V of the regime in force at the row): trueR its RMS, trueS its RMS
about its mean (the mean is a rotation of the whole sensor, which no level ring observes:
docs/calibrator.md "Heading-error estimate"), trueX its largest; "cov" says whether the bound
covers trueS (arc attempts only). With magcal_drive_adopt --arc-refit COV, the same for the
batch solver with the arc stage on the snapshot's LEVEL samples only (nlv, lv ...).

DRIVE.csv / .json: tools/gen_drive.py (dump and truth); ADOPT.jsonl: magcal_drive_adopt on that
dump (tools/drive/drive_adopt.c: every solve's store and calibration, the batch refits of an
adopting solve's snapshot on all its samples and on its LEVEL samples only).

Per adopting solve it prints:
  - lvl: the calibration's TRUE heading error at level attitude, RMS (and mean) over 360 headings
    of the truth's field in the hard-iron regime of the adoption row (exact for the true
    calibration: 0), i.e. what the calibration itself gets wrong, whatever the road does;
  - drv: its RMS over the drive's clean moving rows of that regime from its row to the next
    adoption, and the floor (the true 3-D calibration on the same rows);
  - the store: samples, the share NOT level-tagged (tilted / unknown), the share with true
    |pitch| > 1 deg, their mean |pitch|, the same for the solver's inliers;
  - refit_all / refit_level: the batch solver on the snapshot / on its level samples only, lvl.
Stored samples are matched to their rows by their exact float32 values.
"""
import csv
import json
import math
import os
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
from gen_drive import dcm_ned_batch as dcm  # noqa: E402  (the generator's own attitude, body x right, y forward, z up)

D2R = math.pi / 180.0


def wrap(a):
    return (a + 180.0) % 360.0 - 180.0



def heading(cal, raw):
    o = np.array(cal["offset"])
    m = np.array(cal["m"])
    h = (raw[:, :2] - o) @ m.T
    return np.degrees(np.arctan2(-h[:, 0], h[:, 1]))


def level_grid(T, b_ned, step_on):
    """Raw level samples of the regime (360 headings) and the true headings, deg."""
    yaw = np.arange(360.0) * D2R
    body = np.einsum("nji,j->ni", dcm(np.zeros(360), np.zeros(360), yaw), b_ned)
    tc = T["cal_after"] if step_on else T["cal_before"]
    return body @ np.linalg.inv(np.array(tc["g"])).T + np.array(tc["v"]), np.degrees(yaw)


def all_attempts(argv):
    """--all: every solve attempt against the truth (module docstring)."""
    T = json.load(open(argv[2]))
    decl = T["declination_deg"]
    b_ned = np.array(T["b_ned_ut"])
    step, yaw = [], []
    with open(argv[1]) as f:
        rd = csv.reader(line for line in f if not line.startswith("#"))
        hdr = next(rd)
        ix = {k: i for i, k in enumerate(hdr)}
        for r in rd:
            step.append(float(r[ix["step"]]) > 0)
            yaw.append(float(r[ix["heading_ref_deg"]]))
    turn = np.concatenate([[0.0], np.cumsum(np.abs(wrap(np.diff(np.array(yaw)))))])
    grids = {False: level_grid(T, b_ned, False), True: level_grid(T, b_ned, True)}
    print("%-6s %5s %-12s %4s %3s %6s %5s %4s | %5s %5s %5s %-3s | %3s %-12s %4s %6s %5s %5s %-3s" % (
        "row", "turn", "status", "cov", "arc", "bound", "noise", "used", "trueR", "trueS", "trueX", "cov",
        "nlv", "lv status", "cov", "bound", "trueR", "trueS", "cov"))

    def truth(c, raw_lvl, true_h):
        if c is None or not c["radius"] > 0:
            return float("nan"), float("nan"), float("nan")
        e = wrap(heading(c, raw_lvl) + decl - true_h)
        return np.sqrt(np.mean(e * e)), np.std(e), np.max(np.abs(e))

    f = lambda v, w=6: ("%" + str(w) + ".2f") % v if v is not None else " " * (w - 1) + "-"

    def covered(arc, b, ts):
        if not arc or b is None or not np.isfinite(ts):
            return "-"
        return "yes" if b >= ts else "NO"

    for line in open(argv[3]):
        if not line.startswith("{\"solve\""):
            continue
        s = json.loads(line)
        row = s["solve"]
        raw_lvl, true_h = grids[step[row]]
        tr, ts, tx = truth(s.get("cand"), raw_lvl, true_h)
        b = s.get("arc_bound")
        lv = s.get("arc_level") or {}
        lr, ls, _ = truth(lv.get("cand"), raw_lvl, true_h) if lv.get("status") not in (None,) else (float("nan"),) * 3
        lb = lv.get("arc_bound")
        print("%-6d %5.0f %-12s %4.0f %3d %s %s %4d | %5.2f %5.2f %5.2f %-3s | %3d %-12s %4.0f %s %5.2f %5.2f %-3s" % (
            row, turn[row], s["status"][:12], s["coverage"], s.get("arc", 0), f(b), f(s.get("noise"), 5), s.get("used", 0), tr, ts, tx, covered(s.get("arc"), b, ts),
            lv.get("n", 0), lv.get("status", "-")[:12], lv.get("coverage", 0), f(lb), lr, ls,
            covered(lv.get("arc"), lb, ls)))
    return 0


def main(argv):
    if len(argv) == 5 and argv[1] == "--all":
        return all_attempts(argv[1:])
    if len(argv) != 4:
        print(__doc__)
        return 2
    rows = []
    with open(argv[1]) as f:
        rd = csv.reader(line for line in f if not line.startswith("#"))
        hdr = next(rd)
        ix = {k: i for i, k in enumerate(hdr)}
        for r in rd:
            rows.append([float(r[ix[k]]) for k in ("mx", "my", "mz", "pitch_deg", "roll_deg", "heading_ref_deg",
                                                   "glitch", "disturbed", "step", "parked")])
    a = np.array(rows)
    raw = a[:, 0:3]
    pitch, ref = a[:, 3], a[:, 5]
    glitch, dist, step, park = a[:, 6] > 0, a[:, 7] > 0, a[:, 8] > 0, a[:, 9] > 0
    T = json.load(open(argv[2]))
    decl = T["declination_deg"]
    b_ned = np.array(T["b_ned_ut"])
    key = {}
    r32 = raw.astype(np.float32)
    for i in range(len(r32)):
        key.setdefault((r32[i, 0], r32[i, 1], r32[i, 2]), i)
    # level grid: 360 headings at zero pitch and roll
    yaw = np.arange(360.0) * D2R
    body = np.einsum("nji,j->ni", dcm(np.zeros(360), np.zeros(360), yaw), b_ned)
    solves = [json.loads(line) for line in open(argv[3]) if line.startswith("{\"solve\"")]
    adopt_rows = [s["solve"] for s in solves if s["outcome"] == 2]
    print("%-7s %-4s %6s %5s | %-13s | %-12s | %4s %5s %5s %4s | %5s %5s | %-15s | %-15s" % (
        "row", "reg", "est", "cov", "lvl rms/mean", "drv rms/floor", "n", "!lvl", "p>1", "|p|", "in!lv", "inp>1",
        "refit_all", "refit_level"))
    for s in solves:
        if s["outcome"] != 2:
            continue
        row = s["solve"]
        reg = "after" if step[row] else "before"
        tc = T["cal_after"] if step[row] else T["cal_before"]
        g = np.array(tc["g"])
        v = np.array(tc["v"])
        raw_lvl = body @ np.linalg.inv(g).T + v
        true_h = np.degrees(yaw)

        def lvl(cal):
            e = wrap(heading(cal, raw_lvl) + decl - true_h)
            return np.sqrt(np.mean(e * e)), np.mean(e)

        nxt = [r for r in adopt_rows if r > row]
        end = nxt[0] if nxt else len(a)
        sel = np.zeros(len(a), bool)
        sel[row:end] = True
        sel &= ~glitch & ~dist & ~park & (step == step[row])
        e = wrap(heading(s["cal"], raw[sel]) + decl - ref[sel])
        hf = (raw[sel] - v) @ g.T
        fe = wrap(np.degrees(np.arctan2(-hf[:, 0], hf[:, 1])) + decl - ref[sel])
        st = s["store"]
        idx = np.array([key.get((np.float32(x), np.float32(y), np.float32(z)), -1) for x, y, z, _, _ in st])
        lv = np.array([q[3] for q in st])
        inl = np.array([q[4] for q in st])
        ok = idx >= 0
        p = np.abs(pitch[idx[ok]])
        pin = np.abs(pitch[idx[ok & (inl == 1)]])
        lr, lm = lvl(s["cal"])

        def rf(k):
            r = s.get(k)
            if r is None or "cal" not in r:
                return "%3d %s" % (r["n"] if r else 0, (r or {}).get("status", "-")[:10])
            x, y = lvl(r["cal"])
            return "%3d %5.2f/%+5.2f" % (r["n"], x, y)

        print("%-7d %-4s %6.2f %5.0f | %5.2f / %+5.2f | %5.2f / %4.2f | %4d %5.2f %5.2f %4.2f | %5.2f %5.2f | %-15s | %-15s" % (
            row, reg[:4], s["est_err"], s["coverage"], lr, lm,
            np.sqrt(np.mean(e * e)) if len(e) else float("nan"), np.sqrt(np.mean(fe * fe)) if len(fe) else float("nan"),
            len(st), np.mean(lv == 0), np.mean(p > 1.0), np.mean(p),
            np.mean(lv[inl == 1] == 0) if np.any(inl == 1) else float("nan"),
            np.mean(pin > 1.0) if len(pin) else float("nan"), rf("refit_all"), rf("refit_level")))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
