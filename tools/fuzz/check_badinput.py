#!/usr/bin/env python3
"""Bad-input CTest cases of magcal-replay that the harness's own cases (tools/replay/tests/
check_replay.py) and tests/test_replay_csv.c do not cover (docs/reliability.md "Bad input table").

  check_badinput.py --exe magcal-replay --source-dir REPO --work-dir DIR CASE

Each case writes its dump into DIR, runs the tool and checks the exit status (0 ok, 2 input
error) and the exact FILE:LINE:COL message. Standard library only.
"""
import argparse
import json
import os
import subprocess
import sys


def fail(msg):
    print("FAIL: " + msg)
    sys.exit(1)


def run(a, args, want_rc):
    p = subprocess.run([a.exe] + args, capture_output=True, text=True, timeout=120)
    if p.returncode != want_rc:
        fail("%r: exit %d, expected %d\nstderr: %s" % (args, p.returncode, want_rc, p.stderr))
    return p


def write(a, name, text):
    path = os.path.join(a.work_dir, name)
    with open(path, "w", newline="") as f:
        f.write(text)
    return path


def input_error(a, name, text, msg):
    path = write(a, name, text)
    p = run(a, [path], 2)
    if msg not in p.stderr:
        fail("%s: stderr %r lacks %r" % (name, p.stderr.strip(), msg))
    if p.stdout != "":
        fail("%s: stdout not empty on an input error" % name)


def clean_rows(a):
    """(header, rows) of the bundled synthetic clean dump, comments dropped."""
    path = os.path.join(a.source_dir, "tests", "data", "synthetic", "clean.csv")
    with open(path) as f:
        lines = [l.rstrip("\n") for l in f if l.strip() and not l.lstrip().startswith("#")]
    return lines[0], lines[1:]


def case_csv_huge_value(a):
    # finite as a double, beyond FLT_MAX as float32: rejected by the parser (was +Inf in fill())
    input_error(a, "huge.csv", "t,mx,my\n0,1,2\n0.1,6E92,2\n",
                'huge.csv:3:2: number out of range, got "6E92" (column mx)')
    input_error(a, "huge_neg.csv", "t,mx,my\n0,1,-3.5e38\n",
                'huge_neg.csv:2:3: number out of range, got "-3.5e38" (column my)')


def case_csv_inf_cell(a):
    input_error(a, "inf.csv", "mx,my\n1,inf\n", 'inf.csv:2:2: expected a number, got "inf" (column my)')
    input_error(a, "neg_inf.csv", "mx,my\n-Infinity,1\n",
                'neg_inf.csv:2:1: expected a number, got "-Infinity" (column mx)')


def case_csv_too_many_fields(a):
    hdr = ",".join("c%d" % i for i in range(5000))
    input_error(a, "wide.csv", "mx,my," + hdr + "\n", "wide.csv:1: header has 5002 fields, more than the limit 4096")


def case_csv_long_ignored_cell(a):
    # a 100 kB cell in an unrecognised column is skipped unread: same calibration as without it
    hdr, rows = clean_rows(a)
    plain = write(a, "clean_plain.csv", hdr + "\n" + "\n".join(rows) + "\n")
    body = [r + "," + ("x" * 100000 if i == 7 else "") for i, r in enumerate(rows)]
    longp = write(a, "clean_long_cell.csv", hdr + ",note\n" + "\n".join(body) + "\n")
    ref = json.loads(run(a, ["--json", plain], 0).stdout)
    got = json.loads(run(a, ["--json", longp], 0).stdout)
    for k in ("status", "center", "correction", "radius", "n_outliers", "heading_rms_deg"):
        if ref.get(k) != got.get(k):
            fail("long cell changed %s: %r != %r" % (k, got.get(k), ref.get(k)))


CASES = {k[5:]: v for k, v in globals().items() if k.startswith("case_")}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--exe", required=True)
    ap.add_argument("--source-dir", required=True)
    ap.add_argument("--work-dir", required=True)
    ap.add_argument("case", choices=sorted(CASES))
    a = ap.parse_args()
    os.makedirs(a.work_dir, exist_ok=True)
    CASES[a.case](a)
    print("PASS " + a.case)


if __name__ == "__main__":
    main()
