#!/usr/bin/python3
"""Independent float64 reference for the recorded-dump tests (tests/test_calibrator.c and
tests/test_shared_calibrator.c): radius spread std/mean of |p| (raw, identity calibration) and of
|M (p - c)| after the plain 5-parameter least-squares ellipse fit (centred + scaled, algorithms.md
2.1-2.4, symmetric whitening) of every non-glitch row. No ellipse correction can do much better than
this optimum, so it bounds the achievable spread drop.

    /usr/bin/python3 tools/ref_real_spread.py CSV [xcol ycol]
"""
import sys

import numpy as np


def spread(x, y):
    mx, my = x.mean(), y.mean()
    s = np.max(np.hypot(x - mx, y - my))
    u, v = (x - mx) / s, (y - my) / s
    W = np.stack([u * v, v * v, u, v, np.ones_like(u)], 1)
    A, B, C, D, E = np.linalg.lstsq(W, -u * u, rcond=None)[0]
    dl = 4 * B - A * A
    x0, y0 = (A * D - 2 * B * C) / dl, (A * C - 2 * D) / dl
    w, V = np.linalg.eigh(np.array([[1, A / 2], [A / 2, B]]))
    S = V @ np.diag(np.sqrt(w)) @ V.T
    h = np.stack([u - x0, v - y0], 1) @ S.T
    r = np.hypot(h[:, 0], h[:, 1])
    rr = np.hypot(x, y)
    return rr.std() / rr.mean(), r.std() / r.mean()


def main(argv):
    xc, yc = (argv[2], argv[3]) if len(argv) > 3 else ("mx", "my")
    d = np.genfromtxt(argv[1], delimiter=",", names=True)
    x, y = d[xc], d[yc]
    keep = np.isfinite(x) & np.isfinite(y)
    if "glitch" in d.dtype.names:
        keep &= d["glitch"] < 0.5
    raw, cor = spread(x[keep], y[keep])
    print("%s: rows %d raw %.5f LS-optimal %.5f ratio %.3f" % (argv[1], keep.sum(), raw, cor, raw / cor))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
