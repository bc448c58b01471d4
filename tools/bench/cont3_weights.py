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
With the dirty tumble (cont3_trace_dirty.elf: the solves run the density stage) it also fits the
density stage's weights (src/filter/optics3_internal.h W3_*) to the measured steps (C3O3 lines).
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


# The density stage's weights (src/filter/optics3_internal.h W3_*), in the order of its trace
# counters (P3_*), then the total it charged (including the 2-D selection / heapsort primitives'
# own charges, optics_slice.h W_SEL / W_HS / W_HSL).
W3 = ["W3_FIN", "W3_PAIR", "W3_GATHER", "W3_RAD", "W3_KEY", "W3_MARK", "W3_BAND", "W3_INIT", "W3_SKIP", "W3_CAND",
      "W3_REACH", "W3_UPD", "W3_POP", "W3_GRIDP", "W3_GRIDB", "W3_LABEL", "W3_WIDE", "W3_OUT", "W3_PHASE"]


def w3_current():
    import os
    import re
    hdr = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "src", "filter", "optics3_internal.h")
    with open(hdr) as fh:
        txt = fh.read()
    return {m.group(1): int(m.group(2)) for m in re.finditer(r"#define (W3_\w+) (\d+)", txt)}


def solve_ls(rows, ys, ridge=1e-6):
    """Least squares by the normal equations (Gauss-Jordan with partial pivoting; no numpy)."""
    k = len(rows[0])
    ata = [[0.0] * k for _ in range(k)]
    aty = [0.0] * k
    for r, y in zip(rows, ys):
        for i in range(k):
            if r[i]:
                aty[i] += r[i] * y
                for j in range(k):
                    ata[i][j] += r[i] * r[j]
    for i in range(k):
        ata[i][i] += ridge * (ata[i][i] + 1.0)
    m = [ata[i] + [aty[i]] for i in range(k)]
    for c in range(k):
        piv = max(range(c, k), key=lambda i: abs(m[i][c]))
        m[c], m[piv] = m[piv], m[c]
        if abs(m[c][c]) < 1e-12:
            continue
        for i in range(k):
            if i != c:
                f = m[i][c] / m[c][c]
                m[i] = [a - f * b for a, b in zip(m[i], m[c])]
    return [m[i][k] / m[i][i] if abs(m[i][i]) > 1e-12 else 0.0 for i in range(k)]


def density_fit(dsteps):
    """Fit measured step instructions (minus the drain's) = c0 + sum w_k visits_k + b x (the
    primitives' charge); print the fitted weights next to the ones in the header, and the largest
    measured / charged step of the density stage."""
    cur = w3_current()
    used = [i for i in range(len(W3)) if any(d[3 + i] for d in dsteps)]
    rows, ys = [], []
    for d in dsteps:
        v = d[3:3 + len(W3)]
        other = d[3 + len(W3)] - sum(cur.get(W3[i], 0) * v[i] for i in range(len(W3)))
        rows.append([1.0] + [float(v[i]) for i in used] + [float(max(other, 0))])
        ys.append(float(d[1] - d[2]))
    x = solve_ls(rows, ys)
    print("\ndensity stage (C3O3: %d steps): fitted M4F instructions per visit (trace build)" % len(dsteps))
    print("%-10s %10s %8s %8s" % ("weight", "visits", "fitted", "header"))
    print("%-10s %10s %8.0f" % ("(step)", "-", x[0]))
    fitted = {}
    for j, i in enumerate(used):
        fitted[W3[i]] = x[1 + j]
        print("%-10s %10d %8.1f %8d" % (W3[i], sum(d[3 + i] for d in dsteps), x[1 + j], cur.get(W3[i], 0)))
    print("%-10s %10s %8.2f %8s" % ("primitives", "-", x[-1], "x1"))
    worst = max(dsteps, key=lambda d: d[1])
    ratio = max((d[1] - d[2]) / d[3 + len(W3)] for d in dsteps if d[3 + len(W3)] >= 1000)
    print("largest density step: %d measured (row %d, drain %d), %d charged; worst measured/charged %.2f"
          % (worst[1], worst[0], worst[2], worst[3 + len(W3)], ratio))
    return {"fitted": fitted, "step_const": x[0], "primitives_scale": x[-1], "largest": worst[1],
            "worst_ratio": ratio}


def main(argv):
    a, out = trace_run(argv, __doc__)
    steps, pieces, dsteps = [], [], []
    for ln in out.splitlines():
        f = ln.split()
        if f and f[0] == "C3O3":
            dsteps.append([int(v) for v in f[1:]])
        elif f and f[0] == "C3TR":
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
    dens = density_fit(dsteps) if dsteps else None
    if a.json:
        with open(a.json, "w") as fh:
            json.dump({"pieces": pieces, "units": summary, "largest": top, "density": dens}, fh, indent=1)


if __name__ == "__main__":
    main(sys.argv[1:])
