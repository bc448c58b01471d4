#!/usr/bin/env python3
"""CTest checker for magcal-geomag (standard library only).

    check_cli.py CLI --args A B C D [--model M] (--expect K=V ... [--tol-nt T] [--tol-deg T]
                                                | --expect-fail)

Runs CLI with the arguments, then checks that stdout is ONE JSON object with exactly the names
declination_deg, inclination_deg, F_nT, H_nT, X_nT, Y_nT, Z_nT (finite numbers) and that each
expected value is met within its tolerance (nT names: --tol-nt, deg names: --tol-deg); or, with
--expect-fail, that the CLI exits non-zero with a message on stderr and nothing on stdout.
"""
import json
import math
import subprocess
import sys

OPTIONS = {"--expect", "--tol-nt", "--tol-deg", "--expect-fail", "--expect-keys-only"}
KEYS = {"declination_deg", "inclination_deg", "F_nT", "H_nT", "X_nT", "Y_nT", "Z_nT"}


def main(argv):
    cli = argv[1]
    rest = argv[2:]
    args, expect, mode = [], {}, "values"
    tol_nt, tol_deg = 0.1, 0.01
    i = 0
    while i < len(rest):
        a = rest[i]
        if a == "--args":
            # everything up to the next checker option goes to the CLI (incl. --model M)
            i += 1
            while i < len(rest) and rest[i] not in OPTIONS:
                args.append(rest[i])
                i += 1
            continue
        if a == "--expect":
            i += 1
            while i < len(rest) and "=" in rest[i]:
                k, v = rest[i].split("=", 1)
                expect[k] = float(v)
                i += 1
            continue
        if a == "--tol-nt":
            tol_nt = float(rest[i + 1])
            i += 2
            continue
        if a == "--tol-deg":
            tol_deg = float(rest[i + 1])
            i += 2
            continue
        if a == "--expect-fail":
            mode = "fail"
        elif a == "--expect-keys-only":
            mode = "keys"
        else:
            print("check_cli.py: unknown option " + a)
            return 2
        i += 1
    proc = subprocess.run([cli] + args, capture_output=True, text=True, timeout=20)
    print("$ %s %s -> exit %d" % (cli, " ".join(args), proc.returncode))
    print("stdout: " + proc.stdout.strip())
    print("stderr: " + proc.stderr.strip())
    if mode == "fail":
        ok = proc.returncode != 0 and proc.stderr.strip() != "" and proc.stdout.strip() == ""
        print("expected failure: " + ("ok" if ok else "NOT MET"))
        return 0 if ok else 1
    if proc.returncode != 0:
        print("FAIL: non-zero exit")
        return 1
    try:
        obj = json.loads(proc.stdout)
    except ValueError as e:
        print("FAIL: not JSON: %s" % e)
        return 1
    if not isinstance(obj, dict) or set(obj.keys()) != KEYS:
        print("FAIL: names %s, want exactly %s" % (sorted(obj), sorted(KEYS)))
        return 1
    bad = [k for k, v in obj.items() if not isinstance(v, (int, float)) or not math.isfinite(v)]
    if bad:
        print("FAIL: non-numeric " + ", ".join(bad))
        return 1
    worst = 0
    for k, want in expect.items():
        tol = tol_deg if k.endswith("_deg") else tol_nt
        err = abs(obj[k] - want)
        print("  %-16s got %12.4f want %12.4f |err| %.4f (tol %g)" % (k, obj[k], want, err, tol))
        if err > tol:
            worst = 1
    if worst:
        print("FAIL: outside tolerance")
    return worst


if __name__ == "__main__":
    sys.exit(main(sys.argv))
