#!/usr/bin/python3
"""Per-transient and per-false-flag-episode analysis of a stream replay of a generated drive
(issue 13's disturbance recall and false-flag rate, docs/calibrator.md "Judge and change
detection").

    flag_episodes.py --workdir DIR --tag s3_m60 [--trace TRACE.csv] [--json]

DIR is a check_stream.py --workdir after a run (drive_TAG.csv, drive_TAG.json,
stream_TAG_headings.csv). The row selections are check_stream.py's: from the first adoption on,
without the rows from the hard-iron step to the relearn (the first adoption after the first
`changed` row; the end of the drive without one). Recall counts disturbed rows not marked ok,
false flags clean (not disturbed, not glitch) rows marked disturbed.

Per transient (the truth JSON's `transients`): rows counted, rows missed (trusted) in its rise
(first quarter), middle and fall (last quarter), the true relative change of the field magnitude
at its peak (|G (m - V)| / F - 1 of the truth calibration), of the horizontal magnitude (peak_dh: what |h| / R
sees) and its vertical part over the horizontal field (peak_dz: what the judge's u sees), the
generation in force, parked share, mean |pitch|, seconds since that generation's adoption.
Per false-flag episode (runs of flagged clean rows, gaps < 1 s merged): start row, rows,
seconds, generation, parked share, mean |pitch|, turn rate, seconds since adoption.

--trace: optional per-row judge state (columns row, rel, e, base, sd, sigma, flag, unfit, ep,
...; a debugging print of the replay, not part of the tree): adds the transient judge's
threshold (max(4 sd, sigma, 0.004)) at the start of each transient / episode, the largest
|e - base| inside it, and whether the rows were flagged by the transient judge (flag) or by
the per-sample judge.
"""
import argparse
import csv
import json
import os
import sys

try:
    import numpy as np
except ImportError:
    print("flag_episodes: numpy missing, skipped")
    sys.exit(77)

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from gen_drive import B_NED, D2R, dcm_ned_batch  # noqa: E402  (the drive's own body-field model)

RATE = 50.0


def wrap180(a):
    return (a + 180.0) % 360.0 - 180.0


def runs(mask, gap):
    """[start, end) runs of True in mask, runs separated by fewer than gap False rows merged."""
    idx = np.flatnonzero(mask)
    if idx.size == 0:
        return []
    out = []
    s = idx[0]
    p = idx[0]
    for k in idx[1:]:
        if k - p > gap:
            out.append((int(s), int(p) + 1))
            s = k
        p = k
    out.append((int(s), int(p) + 1))
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--workdir", required=True)
    ap.add_argument("--tag", required=True, help="e.g. s3_m60 or s2_m60_nostep")
    ap.add_argument("--trace", default=None)
    ap.add_argument("--headings", default=None,
                    help="headings CSV of the replay (default: DIR/stream_TAG_headings.csv)")
    ap.add_argument("--json", action="store_true", help="print JSON instead of tables")
    a = ap.parse_args()
    dump = os.path.join(a.workdir, "drive_%s.csv" % a.tag)
    truth = json.load(open(os.path.join(a.workdir, "drive_%s.json" % a.tag)))
    with open(dump) as f:
        f.readline()
        names = f.readline().strip().split(",")
    A = np.loadtxt(dump, delimiter=",", skiprows=2, ndmin=2)
    D = {k: A[:, i] for i, k in enumerate(names)}
    H = list(csv.DictReader(open(a.headings or os.path.join(a.workdir, "stream_%s_headings.csv" % a.tag))))
    n = A.shape[0]
    trust = np.array([h["trust"] for h in H])
    gen = np.array([int(h["generation"]) for h in H])
    ref = D["heading_ref_deg"]
    rate_dps = np.concatenate([[0.0], np.abs(wrap180(np.diff(ref)))]) * RATE
    pitch = np.abs(D["pitch_deg"])
    parked = D["parked"] > 0
    step = D["step"] > 0
    dist = D["disturbed"] > 0
    glitch = D["glitch"] > 0
    # true relative field magnitude under the truth calibration (3-D)
    m = np.stack([D["mx"], D["my"], D["mz"]], axis=1)
    rel_true = np.empty(n)
    for key, sel in (("cal_before", ~step), ("cal_after", step)):
        g = np.array(truth[key]["g"])
        v = np.array(truth[key]["v"])
        rel_true[sel] = np.linalg.norm((m[sel] - v) @ g.T, axis=1) / truth[key]["field"] - 1.0
    # the disturbance in the calibrated body frame: G (m - V) minus the true body field C^T B
    C = dcm_ned_batch(D["roll_deg"] * D2R, D["pitch_deg"] * D2R, D["yaw_deg"] * D2R)
    hb = np.einsum("nji,j->ni", C, B_NED)
    hc = np.empty((n, 3))
    for key, sel in (("cal_before", ~step), ("cal_after", step)):
        hc[sel] = (m[sel] - np.array(truth[key]["v"])) @ np.array(truth[key]["g"]).T
    rh = np.linalg.norm(hb[:, :2], axis=1)
    dh_rel = np.linalg.norm(hc[:, :2], axis=1) / rh - 1.0  # 2-D magnitude change (what |h| / R sees)
    dz_rel = (hc[:, 2] - hb[:, 2]) / rh  # vertical part, x the horizontal field (the judge's u)
    # adoption rows (generation changes) and the check's selections
    adopt = np.flatnonzero(np.diff(gen) > 0) + 1
    first = int(adopt[0]) if adopt.size else n
    excl = np.zeros(n, bool)
    if step.any():
        srow = int(np.argmax(step))
        ch = np.flatnonzero((np.arange(n) >= srow) & (trust == "changed"))
        end = n
        if ch.size:
            later = adopt[adopt > ch[0]]
            end = int(later[0]) if later.size else n
        excl[srow:end] = True
    cal_rows = np.arange(n) >= first
    dsel = cal_rows & dist & ~excl
    csel = cal_rows & ~dist & ~glitch & ~excl
    flagged = trust != "ok"
    ff = csel & (trust == "disturbed")
    # adoption row of the generation in force at each row
    ad_row = np.zeros(n, dtype=np.int64)
    for r in adopt:
        ad_row[r:] = r
    since = (np.arange(n) - ad_row) / RATE
    tr = None
    if a.trace:
        T = np.genfromtxt(a.trace, delimiter=",", names=True)
        tr = {k: T[k] for k in T.dtype.names}
        tr["thr"] = np.maximum(np.maximum(4.0 * tr["sd"], tr["sigma"]), 0.004)
        tr["d"] = np.abs(tr["dr"]) if "dr" in tr else np.abs(tr["e"] - tr["base"])
        if "du" in tr:  # the vertical channel (raw z / R less what the heading explains)
            tr["thr_u"] = np.maximum(4.0 * tr["sdu"], 0.02)

    res = {"tag": a.tag, "rows": n, "first_adoption_row": first,
           "disturbance_rows": int(dsel.sum()), "recall": round(float(np.mean(flagged[dsel])), 4) if dsel.any() else None,
           "clean_rows": int(csel.sum()), "false_flag_rate": round(float(np.mean(ff[csel])), 4) if csel.any() else None}
    trs = []
    for s0, s1 in sorted(truth["transients"]):
        sel = np.zeros(n, bool)
        sel[s0:s1] = True
        sel &= dsel
        if not sel.any():
            continue
        dur = s1 - s0
        q = max(1, dur // 4)
        rise = sel.copy()
        rise[s0 + q:] = False
        fall = sel.copy()
        fall[:s1 - q] = False
        mid = sel & ~rise & ~fall
        miss = sel & ~flagged
        e = {"start": s0, "rows": int(sel.sum()), "dur_s": round(dur / RATE, 2),
             "missed": int(miss.sum()), "missed_rise": int((miss & rise).sum()),
             "missed_mid": int((miss & mid).sum()), "missed_fall": int((miss & fall).sum()),
             "peak_rel_true": round(float(np.max(np.abs(rel_true[s0:s1]))), 4),
             "peak_dh": round(float(dh_rel[s0:s1][np.argmax(np.abs(dh_rel[s0:s1]))]), 4),
             "peak_dz": round(float(dz_rel[s0:s1][np.argmax(np.abs(dz_rel[s0:s1]))]), 4),
             "gen": int(gen[s0]), "parked": round(float(np.mean(parked[s0:s1])), 2),
             "pitch": round(float(np.mean(pitch[s0:s1])), 2), "rate_dps": round(float(np.mean(rate_dps[s0:s1])), 1),
             "since_adopt_s": round(float(since[s0]), 1)}
        if tr is not None:
            e["thr"] = round(float(tr["thr"][s0]), 4)
            e["sd"] = round(float(tr["sd"][s0]), 4)
            e["sigma"] = round(float(tr["sigma"][s0]), 4)
            e["max_d"] = round(float(np.max(tr["d"][s0:s1])), 4)
            e["by_transient"] = int(np.sum(tr["flag"][s0:s1] > 0))
            e["unfit"] = int(np.max(tr["unfit"][s0:s1]))
            if "skip" in tr:
                e["skip"] = int(tr["skip"][s0])
            if "du" in tr:
                e["thr_u"] = round(float(tr["thr_u"][s0]), 4)
                e["max_du"] = round(float(np.max(np.abs(tr["du"][s0:s1]))), 4)
        trs.append(e)
    res["transients"] = trs
    eps = []
    for s0, s1 in runs(ff, int(RATE)):
        sel = np.zeros(n, bool)
        sel[s0:s1] = True
        rows = int((sel & ff).sum())
        e = {"start": s0, "rows": rows, "span_s": round((s1 - s0) / RATE, 1), "gen": int(gen[s0]),
             "parked": round(float(np.mean(parked[s0:s1])), 2), "pitch": round(float(np.mean(pitch[s0:s1])), 2),
             "rate_dps": round(float(np.mean(rate_dps[s0:s1])), 1), "since_adopt_s": round(float(since[s0]), 1),
             "near_transient_s": None}
        # distance to the nearest transient (a flag held over the end of a real one)
        dmin = None
        for t0, t1 in truth["transients"]:
            dd = 0 if (s0 < t1 and t0 < s1) else min(abs(s0 - t1), abs(t0 - s1))
            dmin = dd if dmin is None else min(dmin, dd)
        e["near_transient_s"] = round(dmin / RATE, 1) if dmin is not None else None
        if tr is not None:
            e["thr"] = round(float(tr["thr"][s0]), 4)
            e["max_d"] = round(float(np.max(tr["d"][s0:s1])), 4)
            e["by_transient"] = int(np.sum((tr["flag"][s0:s1] > 0) & ff[s0:s1]))
            e["unfit"] = int(np.max(tr["unfit"][s0:s1]))
            e["episode"] = int(np.max(tr["ep"][s0:s1]))
            if "du" in tr:
                e["thr_u"] = round(float(tr["thr_u"][s0]), 4)
                e["max_du"] = round(float(np.max(np.abs(tr["du"][s0:s1]))), 4)
        eps.append(e)
    eps.sort(key=lambda e: -e["rows"])
    res["false_flag_episodes"] = eps
    if a.json:
        print(json.dumps(res, indent=1))
        return 0
    print("%s: recall %s over %d rows, false flags %s over %d clean rows (first adoption row %d)" % (
        a.tag, res["recall"], res["disturbance_rows"], res["false_flag_rate"], res["clean_rows"], first))
    keys = ["start", "rows", "dur_s", "missed", "missed_rise", "missed_mid", "missed_fall", "peak_rel_true", "peak_dh",
            "peak_dz", "gen",
            "parked", "pitch", "rate_dps", "since_adopt_s"]
    if tr is not None:
        keys += ["thr", "sd", "sigma", "max_d", "by_transient", "unfit"] + (["skip"] if "skip" in tr else [])
        keys += ["thr_u", "max_du"] if "du" in tr else []
    print("transients:")
    print(" ".join("%8s" % k[:8] for k in keys))
    for e in trs:
        print(" ".join("%8s" % e[k] for k in keys))
    keys = ["start", "rows", "span_s", "gen", "parked", "pitch", "rate_dps", "since_adopt_s", "near_transient_s"]
    if tr is not None:
        keys += ["thr", "max_d", "by_transient", "unfit", "episode"] + (["thr_u", "max_du"] if "du" in tr else [])
    print("false-flag episodes (%d, largest first):" % len(eps))
    print(" ".join("%8s" % k[:8] for k in keys))
    for e in eps[:25]:
        print(" ".join("%8s" % e[k] for k in keys))
    return 0


if __name__ == "__main__":
    sys.exit(main())
