#!/usr/bin/python3
"""Synthetic 2-D calibration dumps with known truth (magcal pipeline tests).

    /usr/bin/python3 tools/gen_dump.py --all [--out tests/data/synthetic]
    /usr/bin/python3 tools/gen_dump.py SCENARIO [--out DIR]
    /usr/bin/python3 tools/gen_dump.py --list

Each scenario writes DIR/<scenario>.csv and DIR/<scenario>.json (fixed seeds: reproducible).

Model (algorithms.md 1.1, 1.3): Hm = T*H + b + n, H = H0*(-sin psi, cos psi), n ~ N(0, sigma^2 I).
T is taken SYMMETRIC positive definite (pure soft iron, T = R(phi_s) diag(kx, ky) R(phi_s)^T):
the ellipse then determines the whole correction and the symmetric whitening of algorithms.md
2.4(a) has no constant heading offset, so the verification heading error of a fitted calibration
is comparable with the floor directly.  The true correction is H = T^-1 (Hm - b) (radius H0).

CSV layout (header `t,mx,my,mz,heading_ref_deg,outlier`; mz = nan, planar):
  rows [0, n_cal)        calibration turn(s) over `arc_deg`, with the scenario's singular points
                         (outlier = 1 on every injected sample; heading_ref_deg = true heading,
                         also for outliers);
  rows [n_cal, n_rows)   verification: `ver_per_heading` noisy samples at each of the 8
                         cardinal/intercardinal headings, no outliers.
The first lines are `# key: value` comments with the truth (read by tools/csv2c.py into
magcal_test_truth_t): h0, t00, t01, t10, t11, bx, by, sigma, floor_deg, n_cal, n_outliers, ...

floor_deg = heading RMS on the verification rows when the TRUE correction is applied to the same
noisy data (algorithms.md 9: includes the noise shaping by M = T^-1 automatically).

Outliers:
  bursts  - runs of consecutive samples displaced by one common disturbance vector d (plus the
            sample noise); the vehicle keeps turning under them.  'far' bursts: |d| in
            [0.6, 1.6] x radius; 'near' bursts: |d| in [0.18, 0.35] x radius, directed within
            +/-35 deg of the radial direction at the burst's middle (so the burst sits near the
            ring but clearly off it).
  spikes  - isolated single samples (driver-glitch-like): one axis replaced by a saturated or
            zero value, or both axes displaced by 2..8 x radius.
"""
import json
import math
import os
import sys

import numpy as np

HEADER = "t,mx,my,mz,heading_ref_deg,outlier"
VER_HEADINGS = [0.0, 45.0, 90.0, 135.0, 180.0, 225.0, 270.0, 315.0]

BASE = dict(h0=40.0, kx=1.15, ky=0.85, phi_s_deg=25.0, bx=12.0, by=-7.0, sigma=0.2, n_cal=600,
            arc_deg=720.0, start_deg=17.0, ver_per_heading=10, scale=1.0, quantise=False,
            burst_frac=0.0, n_bursts=0, near_frac=0.0, spike_frac=0.0, seed=1)

SCENARIOS = {
    "clean": dict(seed=101),
    "heavy_noise": dict(sigma=2.0, seed=102),
    "outliers_10": dict(burst_frac=0.10, n_bursts=3, near_frac=0.34, seed=103),
    "outliers_25": dict(burst_frac=0.25, n_bursts=5, near_frac=0.4, seed=104),
    "outliers_35": dict(burst_frac=0.35, n_bursts=6, near_frac=0.5, seed=105),
    # raw counts: field spans about +/-2000 LSB, integer quantisation, LSB noise
    "raw_counts": dict(h0=1200.0, kx=1.3, ky=1.0, bx=300.0, by=-450.0, sigma=6.0, quantise=True,
                       seed=106),
    # hard iron five times the (mean) radius
    "hard_iron_5x": dict(bx=160.0, by=-120.0, seed=107),  # |b| = 200 = 5 x 40
    "soft_iron_strong": dict(kx=1.0, ky=0.55, phi_s_deg=30.0, seed=108),
    "arc_300": dict(arc_deg=300.0, n_cal=400, seed=109),
    "n60": dict(arc_deg=360.0, n_cal=60, seed=110),
    "near_ring": dict(burst_frac=0.20, n_bursts=5, near_frac=1.0, seed=111),
    "spikes": dict(spike_frac=0.05, seed=112),
}


def rot(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s], [s, c]])


def field(h0, psi_deg):
    p = np.radians(psi_deg)
    return np.stack([-h0 * np.sin(p), h0 * np.cos(p)], axis=-1)


def heading_deg(h):
    return np.degrees(np.arctan2(-h[..., 0], h[..., 1])) % 360.0


def wrap180(a):
    return (np.asarray(a) + 180.0) % 360.0 - 180.0


def make(name, p):
    rng = np.random.default_rng(p["seed"])
    T = rot(math.radians(p["phi_s_deg"])) @ np.diag([p["kx"], p["ky"]]) @ rot(math.radians(p["phi_s_deg"])).T
    b = np.array([p["bx"], p["by"]])
    h0, sigma, n_cal = p["h0"], p["sigma"], p["n_cal"]
    radius = h0 * math.sqrt(p["kx"] * p["ky"])  # geometric-mean radius of the ellipse

    # calibration turn: monotone headings with a jittered turn rate
    inc = rng.uniform(0.5, 1.5, n_cal)
    cum = np.concatenate([[0.0], np.cumsum(inc)[:-1]]) / np.sum(inc)
    psi_cal = (p["start_deg"] + p["arc_deg"] * cum) % 360.0
    m_cal = field(h0, psi_cal) @ T.T + b + sigma * rng.standard_normal((n_cal, 2))
    outlier = np.zeros(n_cal, dtype=int)
    bursts = []

    n_burst_pts = int(round(p["burst_frac"] * n_cal))
    if p["n_bursts"] > 0 and n_burst_pts > 0:
        nb = p["n_bursts"]
        lens = np.full(nb, n_burst_pts // nb)
        lens[: n_burst_pts - lens.sum()] += 1
        n_near = int(round(p["near_frac"] * nb))
        # place bursts in disjoint slots spread over the calibration segment
        slot = n_cal // nb
        for k in range(nb):
            L = int(lens[k])
            lo = k * slot + 2
            hi = (k + 1) * slot - L - 2
            s = int(rng.integers(lo, max(lo + 1, hi)))
            mid = s + L // 2
            u_mid = m_cal[mid] - b
            radial = math.atan2(u_mid[1], u_mid[0])
            near = k < n_near
            if near:
                mag = rng.uniform(0.18, 0.35) * radius
                ang = radial + math.radians(rng.uniform(-35.0, 35.0)) * 1.0
                if rng.uniform() < 0.5:
                    ang += math.pi  # inward
            else:
                mag = rng.uniform(0.6, 1.6) * radius
                ang = rng.uniform(-math.pi, math.pi)
            d = mag * np.array([math.cos(ang), math.sin(ang)])
            m_cal[s:s + L] += d
            outlier[s:s + L] = 1
            bursts.append(dict(start=s, length=L, kind="near" if near else "far",
                               dx=float(d[0]), dy=float(d[1])))

    n_spikes = int(round(p["spike_frac"] * n_cal))
    spikes = []
    if n_spikes > 0:
        free = np.flatnonzero(outlier == 0)
        idx = np.sort(rng.choice(free[1:-1], n_spikes, replace=False))
        sat = 3.0 * (np.max(np.abs(m_cal)) + radius)
        for i in idx:
            kind = int(rng.integers(0, 3))
            ax = int(rng.integers(0, 2))
            if kind == 0:
                m_cal[i, ax] = sat if rng.uniform() < 0.5 else -sat
            elif kind == 1:
                m_cal[i, ax] = 0.0
                if abs(m_cal[i, ax] - (b[ax])) < 0.3 * radius:  # zero too close to the ring: push
                    m_cal[i, ax] = b[ax] + 1.5 * radius
            else:
                ang = rng.uniform(-math.pi, math.pi)
                m_cal[i] += rng.uniform(2.0, 8.0) * radius * np.array([math.cos(ang), math.sin(ang)])
            outlier[i] = 1
            spikes.append(int(i))

    # verification rows
    nv = p["ver_per_heading"]
    psi_ver = np.repeat(np.array(VER_HEADINGS), nv)
    m_ver = field(h0, psi_ver) @ T.T + b + sigma * rng.standard_normal((len(psi_ver), 2))

    m = np.vstack([m_cal, m_ver])
    if p["quantise"]:
        m = np.round(m)
    psi = np.concatenate([psi_cal, psi_ver])
    out = np.concatenate([outlier, np.zeros(len(psi_ver), dtype=int)])
    n = len(psi)
    t = np.arange(n) * 0.1

    M = np.linalg.inv(T)
    h_true = (m[n_cal:] - b) @ M.T
    err = wrap180(heading_deg(h_true) - psi_ver)
    floor = float(math.sqrt(np.mean(err ** 2)))
    bias = float(np.mean(err))
    # raw (uncalibrated) heading error for reference
    err_raw = wrap180(heading_deg(m[n_cal:]) - psi_ver)

    truth = dict(
        scenario=name, seed=p["seed"], h0=h0, T=T.tolist(), b=b.tolist(), sigma=sigma,
        kx=p["kx"], ky=p["ky"], phi_s_deg=p["phi_s_deg"], axis_ratio=min(p["kx"], p["ky"]) / max(p["kx"], p["ky"]),
        radius_mean=radius, scale=p["scale"], quantised=bool(p["quantise"]),
        arc_deg=p["arc_deg"], start_deg=p["start_deg"], n_cal=n_cal, n_rows=n,
        verification=dict(rows=[n_cal, n], headings_deg=VER_HEADINGS, per_heading=nv),
        n_outliers=int(outlier.sum()), bursts=bursts, spikes=spikes,
        true_correction=dict(M=M.tolist(), b=b.tolist(),
                             note="H = M (Hm - b); heading = atan2(-Hx, Hy); radius h0"),
        floor_deg=floor, floor_bias_deg=bias,
        raw_heading_rms_deg=float(math.sqrt(np.mean(err_raw ** 2))),
        crlb_deg=float(math.degrees(sigma / h0)),
    )
    keys = [("h0", h0), ("t00", T[0, 0]), ("t01", T[0, 1]), ("t10", T[1, 0]), ("t11", T[1, 1]),
            ("bx", b[0]), ("by", b[1]), ("sigma", sigma), ("floor_deg", floor), ("n_cal", n_cal),
            ("n_outliers", int(outlier.sum())), ("arc_deg", p["arc_deg"]), ("seed", p["seed"])]
    lines = ["# scenario: %s" % name]
    lines += ["# %s: %.9g" % (k, v) for k, v in keys]
    lines.append(HEADER)
    for i in range(n):
        if p["quantise"]:
            mx, my = "%d" % m[i, 0], "%d" % m[i, 1]
        else:
            mx, my = "%.6f" % m[i, 0], "%.6f" % m[i, 1]
        lines.append("%.1f,%s,%s,nan,%.4f,%d" % (t[i], mx, my, psi[i], out[i]))
    return "\n".join(lines) + "\n", truth


def main(argv):
    out = "tests/data/synthetic"
    if "--out" in argv:
        out = argv[argv.index("--out") + 1]
    if "--list" in argv:
        print("\n".join(SCENARIOS))
        return 0
    if "--all" in argv:
        names = list(SCENARIOS)
    else:
        names = [a for a in argv[1:] if a in SCENARIOS]
        if not names:
            sys.stderr.write(__doc__)
            return 2
    os.makedirs(out, exist_ok=True)
    for nm in names:
        p = dict(BASE)
        p.update(SCENARIOS[nm])
        csv, truth = make(nm, p)
        with open(os.path.join(out, nm + ".csv"), "w") as f:
            f.write(csv)
        with open(os.path.join(out, nm + ".json"), "w") as f:
            json.dump(truth, f, indent=1)
            f.write("\n")
        print("%-18s rows=%4d outliers=%3d floor=%.4f deg raw=%.2f deg" % (
            nm, truth["n_rows"], truth["n_outliers"], truth["floor_deg"], truth["raw_heading_rms_deg"]))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
