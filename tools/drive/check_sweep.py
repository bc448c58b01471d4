#!/usr/bin/python3
"""The worst OK over many generated drives (issue 13; docs/calibrator.md "Worst OK on 48 drives").

    check_sweep.py --check-stream tools/drive/check_stream.py --gen tools/gen_drive.py
                   --replay magcal-replay --workdir DIR [--minutes 30] [--seeds 1-48] [--jobs 2]
                   [--max-share 0.001] [--python /usr/bin/python3]

Runs check_stream.py --report-only on every seed (a drive with known truth each, through
`magcal-replay --stream`) and sums, over all of them, the OK rows after the first adoption and
those more than 5 deg off the truth. One drive's worst OK can come from a disturbance no magnitude
judge sees (a transient across the field while parked, without a gyro); the sum over 48 drives is
what a user meets. Prints one JSON object (per seed: trusted rows, OK rows beyond 5 deg, worst
OK, false-flag rate; the totals); exit 1 when the OK rows beyond 5 deg exceed --max-share of all
OK rows, 77 when check_stream.py skips (no numpy), 2 when a drive's report is missing.
"""
import argparse
import concurrent.futures
import json
import os
import subprocess
import sys


def seeds_of(spec):
    """'1-48' or '1,5,9' -> a list of ints."""
    out = []
    for part in spec.split(","):
        if "-" in part:
            lo, hi = part.split("-", 1)
            out.extend(range(int(lo), int(hi) + 1))
        else:
            out.append(int(part))
    return out


def run_seed(a, seed):
    wd = os.path.join(a.workdir, "s%d" % seed)
    cmd = [a.python, a.check_stream, "--gen", a.gen, "--replay", a.replay, "--python", a.python,
           "--workdir", wd, "--minutes", str(a.minutes), "--seed", str(seed), "--report-only"]
    p = subprocess.run(cmd, capture_output=True, text=True, check=False)
    if p.returncode == 77:
        return seed, 77, None
    try:
        return seed, p.returncode, json.loads(p.stdout)
    except json.JSONDecodeError:
        sys.stderr.write("seed %d: no report (exit %d)\n%s" % (seed, p.returncode, p.stderr[-2000:]))
        return seed, 2, None


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--check-stream", required=True)
    ap.add_argument("--gen", required=True)
    ap.add_argument("--replay", required=True)
    ap.add_argument("--workdir", required=True)
    ap.add_argument("--python", default=sys.executable)
    ap.add_argument("--minutes", type=float, default=30.0)
    ap.add_argument("--seeds", default="1-48")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--max-share", type=float, default=0.001)
    a = ap.parse_args()
    seeds = seeds_of(a.seeds)
    per = {}
    with concurrent.futures.ThreadPoolExecutor(max_workers=max(1, a.jobs)) as ex:
        for seed, rc, rep in ex.map(lambda s: run_seed(a, s), seeds):
            if rc == 77:
                print(json.dumps({"skipped": "check_stream.py has no numpy"}))
                return 77
            if rep is None:
                return 2
            per[seed] = rep
    ok = sum(r.get("trusted_rows") or 0 for r in per.values())
    over = sum(r.get("ok_rows_over_5_deg") or 0 for r in per.values())
    worst = max((r.get("worst_ok_deg") or 0.0 for r in per.values()), default=0.0)
    out = {
        "seeds": len(seeds),
        "minutes": a.minutes,
        "trusted_rows": ok,
        "ok_rows_over_5_deg": over,
        "share_over_5_deg": round(over / ok, 6) if ok else 0.0,
        "max_share": a.max_share,
        "worst_ok_deg": worst,
        "drives_with_ok": sum(1 for r in per.values() if (r.get("trusted_rows") or 0) > 0),
        "drives_worst_over_5_deg": sum(1 for r in per.values() if (r.get("worst_ok_deg") or 0.0) > 5.0),
        "per_seed": {str(s): {"trusted_rows": r.get("trusted_rows"), "ok_rows_over_5_deg": r.get("ok_rows_over_5_deg"),
                              "worst_ok_deg": r.get("worst_ok_deg"), "false_flag_rate": r.get("false_flag_rate")}
                     for s, r in sorted(per.items())},
    }
    print(json.dumps(out, indent=1))
    return 0 if over <= a.max_share * ok else 1


if __name__ == "__main__":
    sys.exit(main())
