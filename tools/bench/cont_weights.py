#!/usr/bin/env python3
"""Where each continuous-calibrator step's instructions go on the target, and the weights that
fit them (issue 13/14: no single call above 10,000 M4F instructions at the default budget).

Runs cont_trace.elf (tools/bench/m4f_image: main_cont.c against a library built with
MAGCAL_BENCH_TRACE; src/loop/cont_step.c records per step the stage, the samples drained, the
sweep ends, the estimate charged outside the solver, the budget handed to the solver and what it
left, and the solver's phase) under QEMU mps2-an386 -icount shift=0, and prints per kind of step
the measured SysTick count (40-instruction quanta) next to the estimate:
  - drain-only steps, by (samples, sweep ends): measured per sample vs CONT_W_DRAIN / CONT_W_SWEEP;
  - solve steps that stay in one solver phase (calibrator_solve_internal.h cal_phase_t; inside the
    consensus, its own phase): the solver's own instructions (the trace reads SysTick around it)
    / the solver's estimate: a ratio above 1 means that phase's weights are short by that factor.
Build first (run_bench.py writes drives.h and configures the directory):
    cmake --build BUILD/m4f --target cont_trace
    tools/bench/cont_weights.py BUILD/m4f/cont_trace.elf [--json OUT]
"""
import argparse
import collections
import json
import subprocess
import sys

PHASES = ["BBOX", "CHECK", "IDENT", "EXTENT", "PRE_CONS", "PRE_MASK", "FILTER", "FILTER_RUN", "MASKS", "MEAN", "SCALE", "MOMENTS",
          "CIRCLE", "COV_ALL", "COV_F", "THIN", "CONS", "FLAGS0", "PLAIN", "PLAIN_MASK", "GATES", "CO_RES", "CO_GATE", "CO_FIT", "TOCAL", "COVC",
          "DIST", "HARM_N", "VALID", "SHIFT", "HARM_C", "DONE"]
CONS = ["CHECK", "CAND", "MS_FILL", "MS_SORT", "MS_DIFF", "MED_FILL", "MED_SEL", "ANGLE", "SORT", "DRAW",
        "SCORE_RES", "SCORE_SEL", "SCORE_CNT", "START", "START_FIT", "START_RES", "START_SEL", "RINIT",
        "RINIT_MASK", "ROUND", "REFIT", "REFIT_RES", "RT_GATHER", "RT_SEL", "RT_MASK", "FINAL_RES", "OUT"]
STAGES = ["none", "snapshot", "solve", "fit"]
F = ["row", "meas", "st_in", "st_out", "drained", "sweeps", "charged", "sbud", "sleft", "ph_in", "ph_out",
     "worth", "solve_insn", "drain_insn", "visits", "judged", "count_insn", "count_charged", "snap_insn",
     "snap_charged", "rebins", "outcome"]


def phase_name(p):
    if p == 0xFFFF:
        return "idle"
    base, sub = p & 0xFF, p >> 8
    n = PHASES[base] if base < len(PHASES) else str(base)
    if n == "CONS" and sub != 0xFF:
        n += "." + (CONS[sub] if sub < len(CONS) else str(sub))
    return n


def pct(v, q):
    v = sorted(v)
    return v[min(len(v) - 1, int(q * len(v)))] if v else 0


def trace_run(argv, doc):
    """The options of a trace script (ELF, --json, --trace) and the trace text: the saved one, or
    the ELF's output on QEMU (mps2-an386, -icount shift=0). Shared with cont3_weights.py."""
    ap = argparse.ArgumentParser(description=doc, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("elf")
    ap.add_argument("--json")
    ap.add_argument("--trace", help="read a saved trace instead of running QEMU")
    a = ap.parse_args(argv)
    if a.trace:
        with open(a.trace) as fh:
            return a, fh.read()
    return a, subprocess.run(["timeout", "600", "qemu-system-arm", "-M", "mps2-an386", "-display", "none", "-monitor",
                              "none", "-serial", "null", "-semihosting-config", "enable=on,target=native", "-icount",
                              "shift=0", "-kernel", a.elf], capture_output=True, text=True).stdout


def main(argv):
    a, out = trace_run(argv, __doc__)
    rows = []
    for ln in out.splitlines():
        f = ln.split()
        if len(f) == len(F) + 2 and f[0] == "TR":
            d = dict(zip(F, [int(x) for x in f[2:]]))
            d["drive"] = f[1]
            rows.append(d)
    if not rows:
        print("no TR lines (not a cont_trace.elf?)")
        return 1
    res = {"drain": {}, "phases": {}, "stages": {}}
    # drain-only steps (no solve stage at entry or exit, not the coverage-count step)
    dr = collections.defaultdict(list)
    for r in rows:
        if r["st_in"] == 0 and r["st_out"] == 0 and r["worth"] == 0 and r["drained"] > 0:
            dr[(r["drained"], r["sweeps"])].append(r)
    print("drain-only steps: samples, sweep ends -> measured max / p99 / median, estimate charged")
    per_sample = []
    for k in sorted(dr):
        m = [r["meas"] for r in dr[k]]
        est = max(r["charged"] for r in dr[k])
        print("  %d sample(s), %d sweep end(s): %6d steps  max %6d  p99 %6d  median %6d   est %6d  ratio %.2f" % (
            k[0], k[1], len(m), max(m), pct(m, .99), pct(m, .5), est, max(m) / max(est, 1)))
        res["drain"]["%d_%d" % k] = {"steps": len(m), "max": max(m), "p99": pct(m, .99), "median": pct(m, .5),
                                     "est": est}
        if k[1] == 0:
            per_sample += [x / k[0] for x in m]
    med_sample = pct(per_sample, .5)
    # the drain's own instructions (SysTick around it) against what it charged per component:
    # least squares of drain_insn = push x samples + judge x judged + visit x visits + rebin x rebins
    # over the steps without a sweep end (cont_step.c CONT_W_PUSH / JUDGE / VISIT / REBIN), and the
    # largest measured / charged ratio (the weights should keep it <= ~1)
    dd = [r for r in rows if r["drained"] > 0 and r["sweeps"] == 0 and r["drain_insn"] > 0]
    if dd:
        try:
            import numpy as np
            A = np.array([[r["drained"], r["judged"], r["visits"], r["rebins"]] for r in dd], float)
            y = np.array([r["drain_insn"] for r in dd], float)
            coef = np.linalg.lstsq(A, y, rcond=None)[0]
            resid = y - A @ coef
            print("  drain fit (no sweep end, %d steps): push %.0f  judge %.0f  visit %.0f  rebin %.0f  "
                  "residual max %+.0f  min %+.0f" % (len(dd), *coef, resid.max(), resid.min()))
            res["drain_fit"] = {"push": round(coef[0]), "judge": round(coef[1]), "visit": round(coef[2]),
                                "rebin": round(coef[3]), "resid_max": round(resid.max()), "steps": len(dd)}
        except ImportError:
            pass
    for key, meas, est in (("count", "count_insn", "count_charged"), ("snapshot", "snap_insn", "snap_charged")):
        q = [(r[meas], r[est]) for r in rows if r[est] > 0]
        if q:
            ratio = [m / e for m, e in q]
            print("  %s parts: %d  measured max %d  ratio measured / charged p50 %.2f  max %.2f" % (
                key, len(q), max(m for m, _ in q), pct(ratio, .5), max(ratio)))
            res[key] = {"parts": len(q), "max": max(m for m, _ in q), "p50": round(pct(ratio, .5), 3),
                        "max_ratio": round(max(ratio), 3)}
    w = [r["meas"] for r in rows if r["worth"] == 1]
    if w:
        print("  coverage-count steps: %d  max %d  median %d" % (len(w), max(w), pct(w, .5)))
        res["worth"] = {"steps": len(w), "max": max(w), "median": pct(w, .5)}
    # stage steps
    st = collections.defaultdict(list)
    for r in rows:
        if r["st_in"] != 0 or r["st_out"] != 0:
            st[STAGES[r["st_in"] & 0xFF] + ("" if (r["st_in"] >> 8) == 0 else ".%d" % (r["st_in"] >> 8))].append(r)
    print("steps by stage at entry (measured max / p99 / median; estimate charged outside the solver + solver's):")
    for k in sorted(st):
        m = [r["meas"] for r in st[k]]
        e = [r["charged"] + (r["sbud"] - r["sleft"] if r["sbud"] else 0) for r in st[k]]
        print("  %-12s %6d steps  max %6d  p99 %6d  median %6d   est max %6d" % (k, len(m), max(m), pct(m, .99),
                                                                            pct(m, .5), max(e)))
        res["stages"][k] = {"steps": len(m), "max": max(m), "p99": pct(m, .99), "median": pct(m, .5)}
    # solver phases: steps inside one phase, the drain's median per sample subtracted
    ph = collections.defaultdict(list)
    for r in rows:
        if r["sbud"] and r["ph_in"] == r["ph_out"] and r["sbud"] > r["sleft"] and r["sweeps"] == 0:
            solver = r["solve_insn"]  # SysTick around the solver's step (cont_step.c trace)
            ph[phase_name(r["ph_in"])].append((solver / (r["sbud"] - r["sleft"]), solver))
    print("solver phases (steps within one phase): the solver's own measured instructions / its estimate "
          "p50 / p95 / max, largest step")
    for k in sorted(ph, key=lambda x: -pct([v[0] for v in ph[x]], .95)):
        q = [v[0] for v in ph[k]]
        print("  %-18s %6d steps  ratio p50 %.2f  p95 %.2f  max %.2f   largest solver part %6d" % (
            k, len(q), pct(q, .5), pct(q, .95), max(q), max(v[1] for v in ph[k])))
        res["phases"][k] = {"steps": len(q), "p50": round(pct(q, .5), 3), "p95": round(pct(q, .95), 3),
                            "max": round(max(q), 3), "largest_step": max(v[1] for v in ph[k])}
    # phase changes inside a step: the steps that cross into a phase (one-shot units)
    cross = collections.defaultdict(list)
    for r in rows:
        if r["sbud"] and r["ph_in"] != r["ph_out"]:
            cross[phase_name(r["ph_in"]) + " -> " + phase_name(r["ph_out"])].append(r["meas"])
    print("steps that change phase (largest 12 by measured max):")
    for k in sorted(cross, key=lambda x: -max(cross[x]))[:12]:
        print("  %-34s %6d steps  max %6d  median %6d" % (k, len(cross[k]), max(cross[k]), pct(cross[k], .5)))
    res["crossings"] = {k: {"steps": len(v), "max": max(v), "median": pct(v, .5)} for k, v in cross.items()}
    allm = [r["meas"] for r in rows]
    print("largest traced step %d (drive %s row %d)" % (max(allm), *[(r["drive"], r["row"]) for r in rows
                                                                      if r["meas"] == max(allm)][0]))
    if a.json:
        with open(a.json, "w") as f:
            json.dump(res, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
