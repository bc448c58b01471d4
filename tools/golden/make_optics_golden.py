#!/usr/bin/env python3
"""Golden vectors for the magcal OPTICS filter from an independent implementation (scikit-learn).

    /usr/bin/python3 tools/golden/make_optics_golden.py [--shared /work/shared] [--out tests/support]

Writes tests/support/golden_optics.h and golden_optics.c (compiled into the test support
library). For each dataset it runs sklearn.cluster.OPTICS (metric='minkowski', p=2, the default)
with max_eps = eps and min_samples = MinPts, then cluster_optics_dbscan at eps', and stores the
float32 inputs and the ordering-independent expected outputs (algorithms.md 4.5):
  * core distances (sklearn `core_distances_`, inf beyond eps),
  * labels at eps' (cluster_optics_dbscan),
  * reachability recomputed along sklearn's ordering in float64 with exact sqrt distances,
  * sklearn's ordering and raw reachability (for an exact-order comparison where no near tie
    exists; the script checks that).
Inputs are rounded to float32 first so both sides see the same numbers. The script refuses a
dataset with a pair distance or core distance within 1e-6 (relative) of eps or eps' (boundary
points depend on rounding, algorithms.md 4.5).
Needs Debian's python3-sklearn 1.2.1 and numpy.
"""
import argparse
import csv
import math
import os
import sys

import numpy as np
import sklearn
from sklearn.cluster import OPTICS, cluster_optics_dbscan


def ring_with_outliers(seed, n, radius, centre, ratio, sigma, spike_frac, spike_disp, burst):
    rng = np.random.default_rng(seed)
    psi = np.sort(rng.uniform(0.0, 2.0 * np.pi, n))
    x = centre[0] - radius * np.sin(psi) + rng.normal(0.0, sigma, n)
    y = centre[1] + ratio * radius * np.cos(psi) + rng.normal(0.0, sigma, n)
    spikes = rng.uniform(size=n) < spike_frac
    ang = rng.uniform(0.0, 2.0 * np.pi, n)
    x[spikes] += spike_disp * np.cos(ang[spikes])
    y[spikes] += spike_disp * np.sin(ang[spikes])
    if burst is not None:
        start, length, dx, dy = burst
        x[start:start + length] += dx
        y[start:start + length] += dy
    return np.stack([x, y], axis=1)


def real_glitches(shared):
    path = os.path.join(shared, "data", "real", "lsm9ds1_pmodnav_driver_glitches", "data.csv")
    pts = []
    with open(path, newline="") as f:
        for row in csv.DictReader(f):
            pts.append((float(row["mx"]), float(row["my"])))
    return np.array(pts)


def recompute_reach(X, core, ordering, eps):
    """Reachability along a given ordering (algorithms.md 4.1), float64, exact sqrt."""
    n = len(X)
    reach = np.full(n, np.inf)
    done = np.zeros(n, dtype=bool)
    for p in ordering:
        done[p] = True
        if not np.isfinite(core[p]):
            continue
        d = np.sqrt(((X - X[p]) ** 2).sum(axis=1))
        for o in np.nonzero((d <= eps) & ~done)[0]:
            r = max(core[p], d[o])
            if r < reach[o]:
                reach[o] = r
    return reach


def check_boundaries(name, X, core, reach, eps, eps_prime):
    d = np.sqrt(((X[:, None, :] - X[None, :, :]) ** 2).sum(axis=2))
    for e in (eps, eps_prime):
        if np.isfinite(e):
            close = np.abs(d - e) <= 1e-6 * e
            if close.any():
                sys.exit("%s: a pair distance lies within 1e-6 of %g: choose another radius" % (name, e))
    for v in list(core) + list(reach):
        if np.isfinite(v) and abs(v - eps_prime) <= 1e-6 * eps_prime:
            sys.exit("%s: a core/reach value lies within 1e-6 of eps'" % name)


def near_ties(X, core, ordering, eps):
    """Number of steps where the chosen seed beats another by less than 1e-5 relative (or ties)."""
    n = len(X)
    reach = np.full(n, np.inf)
    done = np.zeros(n, dtype=bool)
    count = 0
    for p in ordering:
        cand = np.nonzero(~done & np.isfinite(reach))[0]
        if len(cand) > 1:
            r = np.sort(reach[cand])
            if r[1] - r[0] <= 1e-5 * r[0] and r[1] != r[0]:
                count += 1
        done[p] = True
        if not np.isfinite(core[p]):
            continue
        d = np.sqrt(((X - X[p]) ** 2).sum(axis=1))
        for o in np.nonzero((d <= eps) & ~done)[0]:
            reach[o] = min(reach[o], max(core[p], d[o]))
    return count


def c_float(v):
    if np.isinf(v):
        return "INFINITY"
    t = "%.9g" % v
    if "." not in t and "e" not in t and "inf" not in t:
        t += ".0"
    return t + "f"


def emit_array(out, ctype, name, values, fmt):
    out.append("static const %s %s[%d] = {" % (ctype, name, len(values)))
    line = "   "
    for v in values:
        item = " " + fmt(v) + ","
        if len(line) + len(item) > 100:
            out.append(line)
            line = "   "
        line += item
    out.append(line)
    out.append("};")


def golden_set(out_c, table, name, x64, eps, min_pts, eps_prime, pt_ctype, pt_fmt):
    """One dataset, 2-D or 3-D: run sklearn, check it, append the C arrays to out_c and the
    table row to table; returns (n_clusters, largest, noise, near_ties) for the log line."""
    x = x64.astype(np.float32)
    xd = x.astype(np.float64)
    model = OPTICS(min_samples=min_pts, max_eps=eps, metric="minkowski", p=2,
                   cluster_method="dbscan", eps=eps_prime).fit(xd)
    ordering = model.ordering_
    core = model.core_distances_
    labels = cluster_optics_dbscan(reachability=model.reachability_, core_distances=core,
                                   ordering=ordering, eps=eps_prime)
    assert (labels == model.labels_).all()
    reach_rec = recompute_reach(xd, core, ordering, eps)
    fin = np.isfinite(reach_rec)
    assert (np.isfinite(model.reachability_) == fin).all()
    rel = np.abs(reach_rec[fin] - model.reachability_[fin])
    assert (rel <= 1e-9 * np.maximum(1.0, reach_rec[fin])).all()
    check_boundaries(name, xd, core, reach_rec, eps, eps_prime)
    ties = near_ties(xd, core, ordering, eps)
    nclu = labels.max() + 1
    big = np.bincount(labels[labels >= 0]).max() if nclu > 0 else 0
    emit_array(out_c, pt_ctype, "g_%s_pts" % name, list(x), pt_fmt)
    emit_array(out_c, "float", "g_%s_core" % name, list(core), c_float)
    emit_array(out_c, "float", "g_%s_reach" % name, list(reach_rec), c_float)
    emit_array(out_c, "uint16_t", "g_%s_order" % name, list(ordering), lambda v: "%d" % v)
    emit_array(out_c, "int16_t", "g_%s_labels" % name, list(labels), lambda v: "%d" % v)
    out_c.append("")
    table.append("    {\"%s\", %d, g_%s_pts, %s, %du, %s, g_%s_core, g_%s_reach, g_%s_order, g_%s_labels, %d, %d},"
                 % (name, len(x), name, c_float(eps), min_pts, c_float(eps_prime), name, name, name, name,
                    nclu, ties))
    return nclu, big, int((labels < 0).sum()), ties


def write_golden(out_dir, stem, script, what, pt_ctype, out_c, table):
    """Write <stem>.c (the arrays in out_c, then the set table) and <stem>.h (the set struct:
    only the point type differs by dimension) into out_dir."""
    up = stem.upper()
    out_c.append("const %s_set_t %s_sets[%s_N_SETS] = {" % (stem, stem, up))
    out_c.extend(table)
    out_c.append("};")
    h = """/* Generated by tools/golden/%s: do not edit. */
#ifndef %s_H
#define %s_H

#include <stddef.h>
#include <stdint.h>

#include "magcal/types.h"

/* %s */
typedef struct {
    const char *name;
    size_t n;
    const %s *pts;
    float eps;              /* max_eps (INFINITY allowed) */
    uint16_t min_pts;       /* min_samples */
    float eps_prime;        /* cluster_optics_dbscan eps */
    const float *core;      /* core_distances_ per point (INFINITY = undefined) */
    const float *reach;     /* reachability recomputed along ordering (float64, exact sqrt) */
    const uint16_t *order;  /* sklearn ordering_ */
    const int16_t *labels;  /* cluster_optics_dbscan labels at eps' (-1 = noise) */
    int n_clusters;
    int near_ties;          /* steps where two seeds differ by < 1e-5 relative (0: exact order comparable) */
} %s_set_t;

#define %s_N_SETS %du
extern const %s_set_t %s_sets[%s_N_SETS];

#endif
""" % (script, up, up, what, pt_ctype, stem, up, len(table), stem, stem, up)
    with open(os.path.join(out_dir, stem + ".h"), "w") as f:
        f.write(h)
    with open(os.path.join(out_dir, stem + ".c"), "w") as f:
        f.write("\n".join(out_c) + "\n")


def main():
    ap = argparse.ArgumentParser()
    here = os.path.dirname(os.path.abspath(__file__))
    ap.add_argument("--shared", default=os.path.join(here, "..", "..", "..", "shared"))
    ap.add_argument("--out", default=os.path.join(here, "..", "..", "tests", "support"))
    args = ap.parse_args()

    sets = [
        # name, points, eps, min_pts, eps'
        ("ring_spikes",
         ring_with_outliers(1, 300, 1.0, (0.3, -0.2), 0.8, 0.02, 0.05, 0.6, None), 0.3, 5, 0.12),
        ("raw_burst",
         ring_with_outliers(2, 200, 2000.0, (3000.0, -1500.0), 0.7, 15.0, 0.03, 3000.0, (40, 20, 500.0, 300.0)),
         math.inf, 4, 260.0),
        ("real_glitches", real_glitches(args.shared), 0.1, 4, 0.045),
    ]

    out_c = ["/* Generated by tools/golden/make_optics_golden.py with scikit-learn %s: do not edit. */"
             % sklearn.__version__,
             "/* real_glitches: mx,my of lsm9ds1_pmodnav_driver_glitches/data.csv (sebkm/sensor_fusion,",
             "   Apache-2.0, experiments/mag/mag_bug_driver.csv at c8bffd66), gauss. */",
             "#include <math.h>", "", '#include "golden_optics.h"', ""]
    table = []
    for name, X64, eps, min_pts, eps_prime in sets:
        nclu, _, noise, ties = golden_set(
            out_c, table, name, X64, eps, min_pts, eps_prime, "magcal_vec2_t",
            lambda p: "{%s, %s}" % (c_float(p[0]), c_float(p[1])))
        print("%-14s n=%3d eps=%g MinPts=%d eps'=%g clusters=%d noise=%d near-ties=%d"
              % (name, len(X64), eps, min_pts, eps_prime, nclu, noise, ties))
    write_golden(args.out, "golden_optics", "make_optics_golden.py",
                 "One scikit-learn OPTICS run (algorithms.md 4.5): float32 inputs, expected outputs.",
                 "magcal_vec2_t", out_c, table)


if __name__ == "__main__":
    main()
