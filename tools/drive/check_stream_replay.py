#!/usr/bin/env python3
"""CTest `stream_replay`: magcal-replay --stream on a bundled synthetic dump with known truth
(tests/data/synthetic/clean.csv + clean.json, python3 standard library only).

    check_stream_replay.py --replay magcal-replay --dump clean.csv --truth clean.json --workdir DIR

Runs --steps-per-row 4 (see main). Asserts: exit 0; the calibration in force at the end has the true hard-iron offset within 0.25 % of
h0; heading RMS over trusted rows (against heading_ref_deg) <= 2 x the per-sample noise floor
(sigma / h0 rad); every row is in the headings CSV with the documented columns, trust one of the
documented states, generation = adopted events so far; the JSON has rows, trusted_rows and
events of the documented schema.
"""
import argparse
import csv
import json
import math
import os
import subprocess
import sys


def fail(msg):
    print("check_stream_replay: FAIL: " + msg)
    sys.exit(1)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--replay", required=True)
    ap.add_argument("--dump", required=True)
    ap.add_argument("--truth", required=True)
    ap.add_argument("--workdir", required=True)
    a = ap.parse_args()
    os.makedirs(a.workdir, exist_ok=True)
    hp = os.path.join(a.workdir, "stream_headings.csv")
    # 4 steps per row (a control loop at 4 x the sample rate): a sliced solve is ~1000 steps, and at
    # one step per row this 680-row dump adopts only after its last row (no trusted row to check)
    out = subprocess.run([a.replay, "--stream", "--json", "--steps-per-row", "4", "--headings", hp, a.dump],
                         capture_output=True, text=True)
    if out.returncode != 0:
        fail("exit %d: %s" % (out.returncode, out.stderr))
    rep = json.loads(out.stdout)
    truth = json.load(open(a.truth))
    for k in ("rows", "trusted_rows", "events", "status", "offset", "matrix", "generation", "est_heading_err_deg"):
        if k not in rep:
            fail("JSON lacks " + k)
    if rep["status"] != "ok" or rep["generation"] < 1:
        fail("no calibration at the end: %s" % rep["status"])
    tol = 0.0025 * truth["h0"]
    dx = rep["offset"][0] - truth["b"][0]
    dy = rep["offset"][1] - truth["b"][1]
    if math.hypot(dx, dy) > tol:
        fail("offset %s vs truth %s (> %.3f)" % (rep["offset"], truth["b"], tol))
    floor = math.degrees(truth["sigma"] / truth["h0"])
    if not (rep.get("heading_rms_trusted_deg", 1e9) <= 2.0 * floor):
        fail("trusted heading RMS %s > 2 x floor %.3f" % (rep.get("heading_rms_trusted_deg"), floor))
    rows = list(csv.reader(open(hp)))
    if rows[0] != ["index", "raw_heading_deg", "heading_deg", "trust", "generation", "heading_ref_deg", "error_deg"]:
        fail("headings header %s" % rows[0])
    if len(rows) - 1 != rep["rows"]:
        fail("headings rows %d != %d" % (len(rows) - 1, rep["rows"]))
    adopted = sorted(e["row"] for e in rep["events"] if e["event"] == "adopted")
    trusted = 0
    for r in rows[1:]:
        i = int(r[0])
        if r[3] not in ("ok", "uncalibrated", "disturbed", "changed", "coarse", "tilted"):
            fail("row %d trust %s" % (i, r[3]))
        if int(r[4]) != sum(1 for x in adopted if x <= i):
            fail("row %d generation %s, adopted events %s" % (i, r[4], adopted))
        trusted += r[3] == "ok"
    if trusted != rep["trusted_rows"]:
        fail("trusted rows %d != JSON %d" % (trusted, rep["trusted_rows"]))
    for e in rep["events"]:
        if set(e) != {"row", "event", "status", "heading_err_deg"} or e["event"] not in (
                "adopted", "refused", "change", "disturbance", "shift"):
            fail("event %s" % e)
    print("check_stream_replay: ok (%d rows, %d trusted, generation %d, offset error %.4f, trusted RMS %.3f deg, "
          "floor %.3f)" % (rep["rows"], trusted, rep["generation"], math.hypot(dx, dy),
                           rep["heading_rms_trusted_deg"], floor))
    return 0


if __name__ == "__main__":
    sys.exit(main())
