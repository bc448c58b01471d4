#!/usr/bin/env python3
"""Compare the `XCHECK <name> <value> [<abs tol>]` lines of a host run and a target run.

    xcheck_compare.py [--abs-tol T] HOST_OUTPUT TARGET_OUTPUT        (two saved outputs)
    xcheck_compare.py [--abs-tol T] --run HOST_CMD... -- TARGET_CMD... (run both, e.g. QEMU)

Both runs must exit 0 and print the same names in the same order. A value passes when
|host - target| <= tol, where tol is the line's own third field or --abs-tol (default 1e-3;
in degrees for headings). Names ending in `_deg` are angles: the difference is wrapped to
(-180, 180] first, so 359.9995 and 0.0002 agree. NaN must match NaN. Prints the largest
difference; exit 1 on any mismatch or when there is nothing to compare. Standard library only.
"""
import math
import subprocess
import sys


def parse(text, what):
    out = []
    for ln in text.splitlines():
        parts = ln.split()
        if len(parts) >= 3 and parts[0] == "XCHECK":
            tol = float(parts[3]) if len(parts) > 3 else None
            out.append((parts[1], float(parts[2]), tol))
    if not out:
        raise SystemExit("xcheck: no XCHECK lines in the %s output" % what)
    return out


def run(cmd, what):
    p = subprocess.run(cmd, capture_output=True, text=True)
    if p.returncode != 0:
        sys.stdout.write(p.stdout)
        sys.stderr.write(p.stderr)
        raise SystemExit("xcheck: %s run failed with status %d: %s" % (what, p.returncode, " ".join(cmd)))
    return p.stdout


def main(argv):
    args = argv[1:]
    tol = 1e-3
    if len(args) >= 2 and args[0] == "--abs-tol":
        tol = float(args[1])
        args = args[2:]
    if args and args[0] == "--run":
        if "--" not in args:
            raise SystemExit(__doc__)
        cut = args.index("--")
        host_txt = run(args[1:cut], "host")
        tgt_txt = run(args[cut + 1:], "target")
    elif len(args) == 2:
        host_txt = open(args[0]).read()
        tgt_txt = open(args[1]).read()
    else:
        raise SystemExit(__doc__)
    host = parse(host_txt, "host")
    tgt = parse(tgt_txt, "target")
    if [h[0] for h in host] != [t[0] for t in tgt]:
        raise SystemExit("xcheck: host and target print different names (%d vs %d lines)" % (len(host), len(tgt)))
    bad = 0
    worst = (0.0, "")
    for (name, hv, htol), (_, tv, _) in zip(host, tgt):
        lim = htol if htol is not None else tol
        if math.isnan(hv) or math.isnan(tv):
            d = 0.0 if (math.isnan(hv) and math.isnan(tv)) else math.inf
        else:
            d = tv - hv
            if name.endswith("_deg"):
                d = math.fmod(d, 360.0)
                d = d - 360.0 if d > 180.0 else (d + 360.0 if d <= -180.0 else d)
            d = abs(d)
        if d > worst[0]:
            worst = (d, name)
        if not d <= lim:
            bad += 1
            print("MISMATCH %s host %.9g target %.9g |diff| %.3g > %.3g" % (name, hv, tv, d, lim))
    print("xcheck: %d values, %d mismatches, largest |diff| %.3g (%s), default tol %g"
          % (len(host), bad, worst[0], worst[1] or "-", tol))
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
