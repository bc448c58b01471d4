#!/usr/bin/env python3
"""Where each continuous 3-D calibrator step's instructions go on the target, and the weights that
bound them (issue 13/14: no single call above 10,000 M4F instructions at the default budget).

Runs cont3_trace.elf (tools/bench/m4f_image: main_cont3.c against a library built with
MAGCAL_BENCH_TRACE; src/loop3/c3_step.c records per step the unit at entry and exit, the samples
pushed, the sweep ends, the estimate charged, the solver's own estimate and the instructions of
the drain and of the whole step, and per kind of resumable work its count, largest and summed
instructions next to its weight) under QEMU mps2-an386 -icount shift=0, and prints
  - per kind of work: count, largest and mean measured instructions, the weight charged, and
    largest / weight (above 1: the weight is short; SysTick quantises to 40 instructions, so
    pieces under ~100 read coarse: their mean is the guide);
  - per unit (stage at entry): steps, largest and median measured step;
  - the largest steps with what they did.
The trace image's counts include the trace's own stores and SysTick reads (tens of instructions
per piece): the shipped figure is cont3.elf's (run_bench.py m4f_cont3, m4f_max_call3_instr).
Build first (run_bench.py configures the directory, or see docs/calibration_3d.md "Work per call"):
    cmake --build BUILD/m4f --target cont3_trace
    tools/bench/cont3_weights.py BUILD/m4f/cont3_trace.elf [--json OUT]
"""
import collections
import json
import sys

from cont_weights import trace_run  # same directory: the options and the QEMU run of a trace

PIECES = ["push", "sweep_survey", "sweep_rebin", "sweep_jump", "sweep_end", "count_cell", "count_cell_2+",
          "snapshot_cell", "adopt_candidate", "adopt_installed", "adopt_skip"]
STAGES = ["none", "snapshot", "solve", "adopt", "count"]
F = ["row", "meas", "st_in", "st_out", "pushed", "sweep_ends", "charged", "solver_used", "drain_insn", "body_insn",
     "cells"]


def main(argv):
    a, out = trace_run(argv, __doc__)
    steps, pieces = [], []
    for ln in out.splitlines():
        f = ln.split()
        if f and f[0] == "C3TR":
            steps.append(dict(zip(F, [int(v) for v in f[1:]])))
        elif f and f[0] == "C3PIECE":
            k, n, mx, mean, w = (int(v) for v in f[1:6])
            if n:
                pieces.append({"kind": PIECES[k] if k < len(PIECES) else str(k), "n": n, "max": mx, "mean": mean,
                               "weight": w, "max_over_weight": round(mx / w, 2) if w else None})
    if not steps:
        sys.exit("no C3TR lines: not a cont3_trace.elf, or it failed:\n" + out[-500:])
    print("%-16s %8s %6s %6s %6s %8s" % ("work", "n", "max", "mean", "weight", "max/w"))
    for p in pieces:
        print("%-16s %8d %6d %6d %6d %8s" % (p["kind"], p["n"], p["max"], p["mean"], p["weight"], p["max_over_weight"]))
    units = collections.defaultdict(list)
    for s in steps:
        units[STAGES[s["st_in"] & 0xFF] if (s["st_in"] & 0xFF) < len(STAGES) else str(s["st_in"] & 0xFF)].append(s["meas"])
    print("\n%-10s %8s %8s %8s" % ("unit", "steps", "max", "median"))
    summary = {}
    for u, v in sorted(units.items()):
        v = sorted(v)
        summary[u] = {"steps": len(v), "max": v[-1], "median": v[len(v) // 2]}
        print("%-10s %8d %8d %8d" % (u, len(v), v[-1], v[len(v) // 2]))
    top = sorted(steps, key=lambda s: -s["meas"])[:10]
    print("\nlargest steps (trace image):")
    for s in top:
        print("  row %(row)5d  %(meas)6d insn  drain %(drain_insn)5d  pushed %(pushed)d  sweep ends %(sweep_ends)d  "
              "charged %(charged)5d  solver %(solver_used)5d  cells %(cells)3d" % s,
              "stage %s -> %s" % (STAGES[s["st_in"] & 0xFF], STAGES[s["st_out"] & 0xFF]))
    if a.json:
        with open(a.json, "w") as fh:
            json.dump({"pieces": pieces, "units": summary, "largest": top}, fh, indent=1)


if __name__ == "__main__":
    main(sys.argv[1:])
