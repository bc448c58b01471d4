#!/usr/bin/python3
"""Independent float64 reference for the 3-D replay tests (tools/replay/tests/check_replay.py,
case real_3d): radius spread std/mean of |m| (raw, from the origin) and of |G (m - V)| after a
plain algebraic ellipsoid fit of EVERY row (general 10-parameter quadric, smallest right singular
vector of the centred and scaled design matrix; G = Q^(1/2) symmetric), no outlier rejection.
This is a different formulation from the library's (9-parameter d = -1 quadric with iterative
outlier rejection, src/fit/ellipsoid.c), so agreement is a real cross-check.

    /usr/bin/python3 tools/ref_real_spread3d.py CSV [--json]
"""
import json
import sys

import numpy as np


def fit(m):
    mu = m.mean(0)
    s = np.abs(m - mu).max()
    x, y, z = ((m - mu) / s).T
    D = np.stack([x * x, y * y, z * z, 2 * x * y, 2 * x * z, 2 * y * z, 2 * x, 2 * y, 2 * z, np.ones_like(x)], 1)
    v = np.linalg.svd(D, full_matrices=False)[2][-1]
    A = np.array([[v[0], v[3], v[4]], [v[3], v[1], v[5]], [v[4], v[5], v[2]]])
    b = v[6:9]
    if np.linalg.eigvalsh(A)[0] < 0:
        A, b, v = -A, -b, -v
    c = -np.linalg.solve(A, b)                    # centre (scaled units)
    k = c @ A @ c - v[9]                          # (u - c)^T A (u - c) = k
    Q = A / k
    w, U = np.linalg.eigh(Q)
    G = U @ np.diag(np.sqrt(w)) @ U.T             # unit-radius output
    V = mu + s * c
    h = (m - V) @ G.T / s
    r = np.linalg.norm(h, axis=1)
    rr = np.linalg.norm(m, axis=1)
    return dict(offset=V.tolist(), spread_raw=float(rr.std() / rr.mean()),
                spread_corrected=float(r.std() / r.mean()), rows=int(len(m)))


def main(argv):
    d = np.genfromtxt(argv[1], delimiter=",", names=True, comments="#")
    m = np.stack([d["mx"], d["my"], d["mz"]], 1)
    m = m[np.all(np.isfinite(m), 1)]
    out = fit(m)
    if "--json" in argv:
        print(json.dumps(out))
    else:
        print("%s: rows %d raw %.5f LS %.5f ratio %.3f centre %s" % (
            argv[1], out["rows"], out["spread_raw"], out["spread_corrected"],
            out["spread_raw"] / out["spread_corrected"], np.round(out["offset"], 5)))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
