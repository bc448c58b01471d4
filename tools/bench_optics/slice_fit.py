#!/usr/bin/env python3
"""Fit the per-visit weights of the sliced 2-D density stage (src/filter/optics_slice.h W_*,
src/filter/neighbors.c NBR_W_*) to measured host instruction counts.

For each dataset it runs slice_bench under callgrind with one dump per step call (the host
instructions of every step) and the profile build (MAGCAL_OPTICS_SLICE_PROFILE: the visits
charged per weight in every step), then solves host_instr(step) ~ c0 + sum_w visits_w * c_w by
least squares. The weights to use are about 1.2 x c_w (the contract: M4F ~ host x 1.2).

  slice_fit.py BUILD_DIR PROFILE_BINARY
  (PROFILE_BINARY: gcc -O2 -DMAGCAL_OPTICS_SLICE_PROFILE -Iinclude -Isrc src/filter/optics*.c
   src/filter/neighbors.c src/fit/linalg.c src/status.c tools/bench_optics/slice_bench.c -lm)
"""
import glob
import os
import subprocess
import sys
import tempfile

NAMES = ['FIN', 'SEL', 'HS', 'HSL', 'PAIR', 'GATHER', 'KEY', 'CAP', 'ANGLE', 'LINK', 'SECTOR',
         'INIT', 'SKIP', 'PSTART', 'CAND', 'REACH', 'UPD', 'HEAP', 'POP', 'OUT', 'QUERY', 'PHASE',
         'N_SETUP', 'N_HGROW', 'N_BBOX', 'N_ZERO', 'N_CELL', 'N_PREFIX', 'N_PLACE', 'N_SHIFT']
RUNS = [('filter', d, n, b) for d in ('ring', 'parked', 'burst') for n in (288, 1024)
        for b in (6000, 1500)] + [('thin', d, n, 6000) for d in ('ring', 'parked') for n in (288, 1024)]


def steps_host(bench, what, data, n, budget):
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, 'cg')
        subprocess.run(['valgrind', '--tool=callgrind', '--callgrind-out-file=' + out,
                        '--toggle-collect=magcal_optics_%s_step' % what,
                        '--dump-after=magcal_optics_%s_step' % what,
                        bench, what, data, str(n), str(budget)],
                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=False)
        files = [f for f in glob.glob(out + '.*') if f.rsplit('.', 1)[1].isdigit()]
        files.sort(key=lambda f: int(f.rsplit('.', 1)[1]))
        vals = []
        for f in files:
            with open(f) as fh:
                for line in fh:
                    if line.startswith('summary:'):
                        vals.append(int(line.split()[1]))
        return vals


def steps_prof(prof, what, data, n, budget):
    res = subprocess.run([prof, what, data, str(n), str(budget)], capture_output=True, text=True,
                         check=False)
    rows = []
    for line in res.stdout.splitlines():
        if line.startswith('P '):
            v = [int(x) for x in line.split()[1:]]
            rows.append(v[:22] + v[22:22 + 8])
    return rows


def solve(a, b):
    """Least squares by the normal equations (Gaussian elimination, small ridge)."""
    m = len(a[0])
    ata = [[sum(r[i] * r[j] for r in a) for j in range(m)] for i in range(m)]
    atb = [sum(r[i] * y for r, y in zip(a, b)) for i in range(m)]
    for i in range(m):
        ata[i][i] += 1e-6 * (ata[i][i] + 1.0)
    for c in range(m):
        p = max(range(c, m), key=lambda r: abs(ata[r][c]))
        ata[c], ata[p] = ata[p], ata[c]
        atb[c], atb[p] = atb[p], atb[c]
        for r in range(c + 1, m):
            f = ata[r][c] / ata[c][c]
            for k in range(c, m):
                ata[r][k] -= f * ata[c][k]
            atb[r] -= f * atb[c]
    x = [0.0] * m
    for i in reversed(range(m)):
        x[i] = (atb[i] - sum(ata[i][k] * x[k] for k in range(i + 1, m))) / ata[i][i]
    return x


def main():
    build, prof = sys.argv[1], sys.argv[2]
    bench = os.path.join(build, 'tools', 'bench_optics', 'slice_bench')
    a, b = [], []
    for what, data, n, budget in RUNS:
        h = steps_host(bench, what, data, n, budget)
        p = steps_prof(prof, what, data, n, budget)
        if len(h) != len(p):
            print('step count mismatch', what, data, n, budget, len(h), len(p))
            continue
        print('%s %s %d @%d: %d steps, largest %d host instr' % (what, data, n, budget, len(h), max(h)))
        for hv, pv in zip(h, p):
            a.append([1] + pv)
            b.append(hv)
    used = [j for j in range(len(a[0])) if any(r[j] for r in a)]
    x = solve([[r[j] for j in used] for r in a], b)
    for j, c in zip(used, x):
        name = 'step' if j == 0 else NAMES[j - 1]
        print('%-9s host %8.1f  -> weight %6.0f' % (name, c, 1.2 * c))
    worst = max(abs(y - sum(r[j] * c for j, c in zip(used, x))) for r, y in zip(a, b))
    print('largest residual %.0f host instr over %d steps' % (worst, len(b)))


if __name__ == '__main__':
    main()
