#!/usr/bin/python3
"""Plot a magcal-replay run: what the calibration saw, what it fitted, and what it did to heading.

    /usr/bin/python3 tools/plot_replay.py DUMP.csv --headings H.csv --report R.json [-o OUT.png]

DUMP.csv is the dump given to magcal-replay; H.csv its --headings output; R.json its --json
report (stdout of `magcal-replay --json`). Writes OUT.png (default: DUMP stem + "_replay.png").
Panels:
  1. raw horizontal samples (in the report's field_unit, else dump units) -- the calibration
     samples used and the outliers (counted as the report counts them: fed rows only, so the
     legend gives n_used and n_outliers; rows skipped by the decimation are drawn apart),
     non-calibration rows -- with the fitted ellipse and its centre;
  2. the same samples after the correction h = M (raw - centre), with the circle of the
     calibrated radius (inliers should sit on it);
  3. heading over rows: raw (uncalibrated) and calibrated heading, and the reference if the
     dump has one; the calibration segment shaded;
  4. heading error against the reference over rows (if any), else the corrected radius
     |h| / radius over rows (outliers stand out).
Needs Debian's python3 with matplotlib (Agg backend; no display).
"""
import argparse
import csv
import json
import math
import os
import sys

C_IN, C_OUT, C_OTHER, C_FIT, C_REF = "#1f77b4", "#d62728", "#9e9e9e", "#2ca02c", "#ff7f0e"


def fnum(s):
    try:
        v = float(s)
    except (TypeError, ValueError):
        return math.nan
    return v


def read_dump(path):
    with open(path, newline="") as f:
        lines = [ln for ln in f if ln.strip() and not ln.lstrip().startswith("#")]
    head = lines[0] if lines else ""
    # the separator magcal-replay uses: ',' unless the header has none and has ';' (else a tab)
    sep = "," if "," in head else ";" if ";" in head else "\t" if "\t" in head else ","
    rd = csv.reader(lines, delimiter=sep)
    header = [h.strip().strip('"').lower() for h in next(rd)]
    cols = {h: [] for h in header}
    for row in rd:
        for h, v in zip(header, row):
            cols[h].append(fnum(v.strip().strip('"')))
    return cols


def read_headings(path):
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    out = {k: [fnum(r[k]) for r in rows] for k in rows[0].keys()} if rows else {}
    return out


def unit_of(rep):
    """The field unit the report carries (--field-unit), or "dump units"."""
    u = rep.get("field_unit", "dump")
    return "dump units" if u in (None, "dump") else u


def title_of(rep, dump_path):
    """Figure title: the dump's basename (the report's `file` keeps the path as given)."""
    t = "magcal-replay: %s   (status: %s" % (os.path.basename(dump_path), rep.get("status"))
    e = rep.get("est_heading_err_deg")
    if isinstance(e, (int, float)):
        t += "; estimated heading error %.2f deg" % e
    return t + ")"


def row_groups(rep, flag, n):
    """Rows of panel 1, counted as the report counts them: `used` and `outliers` are the FED
    calibration rows (every k-th with decimation k), so len(used) == n_used and len(outliers) ==
    n_outliers; `not_fed` are calibration rows the decimation skipped; `other` the rest."""
    c0, c1 = rep.get("cal_range", [0, n])
    k = max(int(rep.get("decimation", 1)), 1)
    fed = [c0 <= i < c1 and (i - c0) % k == 0 for i in range(n)]
    return {
        "used": [i for i in range(n) if fed[i] and not flag[i]],
        "outliers": [i for i in range(n) if fed[i] and flag[i]],
        "not_fed": [i for i in range(n) if c0 <= i < c1 and not fed[i]],
        "other": [i for i in range(n) if not c0 <= i < c1],
    }


def legend_labels(rep, groups):
    """Legend texts of panel 1 (their counts match the report's n_used / n_outliers)."""
    lab = {
        "used": "calibration samples used (%d)" % len(groups["used"]),
        "outliers": "outliers (%d)" % len(groups["outliers"]),
        "other": "not calibration rows (%d)" % len(groups["other"]),
    }
    if groups["not_fed"]:
        lab["not_fed"] = "calibration rows skipped by the decimation k = %d (%d)" % (
            int(rep.get("decimation", 1)), len(groups["not_fed"]))
    return lab


def robust_limits(xs, ys, pad=0.25):
    """Square limits around the points given (the inliers), padded."""
    xs = [x for x in xs if math.isfinite(x)]
    ys = [y for y in ys if math.isfinite(y)]
    if not xs:
        return (-1, 1), (-1, 1)
    cx, cy = 0.5 * (min(xs) + max(xs)), 0.5 * (min(ys) + max(ys))
    half = 0.5 * max(max(xs) - min(xs), max(ys) - min(ys)) * (1.0 + pad) or 1.0
    return (cx - half, cx + half), (cy - half, cy + half)


def scatter_clipped(ax, xs, ys, lim, **kw):
    """Scatter; points outside the limits are pinned to the frame edge (marker '>' style kept)."""
    (x0, x1), (y0, y1) = lim
    px, py, n_off = [], [], 0
    for x, y in zip(xs, ys):
        if not (math.isfinite(x) and math.isfinite(y)):
            continue
        if x < x0 or x > x1 or y < y0 or y > y1:
            n_off += 1
        px.append(min(max(x, x0), x1))
        py.append(min(max(y, y0), y1))
    if px:
        ax.scatter(px, py, **kw)
    return n_off


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("dump")
    ap.add_argument("--headings", required=True, help="magcal-replay --headings output")
    ap.add_argument("--report", required=True, help="magcal-replay --json output")
    ap.add_argument("-o", "--output")
    a = ap.parse_args(argv)

    import matplotlib  # here, so the helpers above import without matplotlib (tests)

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Ellipse, Circle

    with open(a.report) as f:
        rep = json.load(f)
    if rep.get("mode", "2d") != "2d":
        sys.stderr.write("plot_replay.py: draws the 2d mode only; this report is --mode %s "
                         "(use the JSON and the --headings CSV)\n" % rep.get("mode"))
        return 2
    dump = read_dump(a.dump)
    hd = read_headings(a.headings)
    out = a.output or os.path.splitext(a.dump)[0] + "_replay.png"

    plane = rep.get("plane", "XY").lower()
    kx, ky = "m" + plane[0], "m" + plane[1]
    mx, my = dump[kx], dump[ky]
    n = len(mx)
    idx = list(range(n))
    c0, c1 = rep.get("cal_range", [0, n])
    is_cal = [c0 <= i < c1 for i in idx]
    flag = [v == 1.0 for v in hd.get("outlier", [0.0] * n)]
    ok = rep.get("status") == "ok"

    fig, axs = plt.subplots(2, 2, figsize=(13, 12))
    fig.suptitle(title_of(rep, a.dump), fontsize=13, fontweight="bold")
    unit = unit_of(rep)

    # ---- 1. raw samples and the fitted ellipse
    ax = axs[0][0]
    groups = row_groups(rep, flag, n)
    labels = legend_labels(rep, groups)
    inl, outl, oth = groups["used"], groups["outliers"], groups["other"] + groups["not_fed"]
    lim = robust_limits([mx[i] for i in inl] + [0.0], [my[i] for i in inl] + [0.0], pad=0.35)
    scatter_clipped(ax, [mx[i] for i in groups["other"]], [my[i] for i in groups["other"]], lim, s=10,
                    c=C_OTHER, label=labels["other"])
    if groups["not_fed"]:
        scatter_clipped(ax, [mx[i] for i in groups["not_fed"]], [my[i] for i in groups["not_fed"]], lim, s=6,
                        c="#c7d7ea", label=labels["not_fed"])
    scatter_clipped(ax, [mx[i] for i in inl], [my[i] for i in inl], lim, s=12, c=C_IN,
                    label=labels["used"])
    off = scatter_clipped(ax, [mx[i] for i in outl], [my[i] for i in outl], lim, s=36, c=C_OUT,
                          marker="x", label=labels["outliers"])
    if ok:
        e = rep["ellipse"]
        ax.add_patch(Ellipse(e["center"], 2 * e["semi_axes"][0], 2 * e["semi_axes"][1],
                             angle=e["angle_deg"], fill=False, lw=2, color=C_FIT, label="fitted ellipse"))
        ax.plot(*e["center"], marker="+", ms=14, mew=2, color=C_FIT, ls="none", label="centre (hard iron)")
    ax.plot(0, 0, marker="o", ms=5, color="k", ls="none", label="origin")
    ax.set_xlim(*lim[0])
    ax.set_ylim(*lim[1])
    ax.set_aspect("equal")
    ax.set_xlabel("%s (%s)" % (kx, unit))
    ax.set_ylabel("%s (%s)" % (ky, unit))
    ax.set_title("1. Raw samples and fitted ellipse" + ("\n%d outliers off-scale, pinned to the frame edge" % off if off else ""))
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.1), ncol=3, fontsize=8)
    ax.grid(alpha=0.3)

    # ---- 2. corrected samples on the circle
    ax = axs[0][1]
    if ok:
        (cx, cy), m, r = rep["center"], rep["correction"], rep["radius"]

        def corr(i):
            u, v = mx[i] - cx, my[i] - cy
            return m[0][0] * u + m[0][1] * v, m[1][0] * u + m[1][1] * v

        hin = [corr(i) for i in inl]
        hout = [corr(i) for i in outl]
        hoth = [corr(i) for i in oth]
        lim2 = ((-1.5 * r, 1.5 * r), (-1.5 * r, 1.5 * r))
        scatter_clipped(ax, [p[0] for p in hoth], [p[1] for p in hoth], lim2, s=10, c=C_OTHER)
        scatter_clipped(ax, [p[0] for p in hin], [p[1] for p in hin], lim2, s=12, c=C_IN, label=labels["used"])
        scatter_clipped(ax, [p[0] for p in hout], [p[1] for p in hout], lim2, s=36, c=C_OUT, marker="x",
                        label=labels["outliers"])
        ax.add_patch(Circle((0, 0), r, fill=False, lw=2, color=C_FIT, label="radius %.4g %s" % (r, unit)))
        ax.plot(0, 0, marker="+", ms=12, color="k")
        ax.set_xlim(*lim2[0])
        ax.set_ylim(*lim2[1])
        ax.set_aspect("equal")
        ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.1), ncol=3, fontsize=8)
        ax.set_title("2. Corrected h = M (raw - centre): on a circle\nradius spread %.2f %% raw -> %.2f %% corrected"
                     % (100 * rep.get("radius_spread_raw_used", rep["radius_spread_raw"]), 100 * rep["radius_spread_corrected"]))
    else:
        ax.text(0.5, 0.5, "calibration failed:\n%s" % rep.get("reason", ""), ha="center", va="center",
                wrap=True, transform=ax.transAxes)
        ax.set_title("2. Corrected samples")
    ax.set_xlabel("h.x (right, %s)" % unit)
    ax.set_ylabel("h.y (forward, %s)" % unit)
    ax.grid(alpha=0.3)

    # ---- 3. heading over rows
    ax = axs[1][0]
    ax.axvspan(c0 - 0.5, c1 - 0.5, color="#e8f0fa", label="calibration rows")
    raw_h, cal_h = hd.get("raw_heading_deg", []), hd.get("heading_deg", [])
    ax.plot(idx, raw_h, ".", ms=3, color=C_OTHER, label="raw heading (no calibration)")
    ax.plot(idx, cal_h, ".", ms=3, color=C_IN, label="calibrated heading")
    if "heading_ref_deg" in hd:
        ref = list(hd["heading_ref_deg"])
        for i in range(1, n):  # break the line where the reference wraps through north
            if abs(ref[i] - ref[i - 1]) > 180.0:
                ref[i - 1] = math.nan
        ax.plot(idx, ref, "-", lw=1.2, color=C_REF, label="reference")
    fl = [i for i in idx if flag[i]]
    ax.plot(fl, [cal_h[i] for i in fl], "x", ms=5, color=C_OUT, label="flagged outlier")
    ax.set_ylim(0, 360)
    ax.set_yticks(range(0, 361, 45))
    ax.set_xlabel("row")
    ax.set_ylabel("heading (deg, clockwise from north)")
    ax.set_title("3. Heading over rows")
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.12), ncol=2, fontsize=8, markerscale=2)
    ax.grid(alpha=0.3)

    # ---- 4. heading error, or corrected radius
    ax = axs[1][1]
    ax.axvspan(c0 - 0.5, c1 - 0.5, color="#e8f0fa", label="calibration rows")
    if "error_deg" in hd and any(math.isfinite(e) for e in hd["error_deg"]):
        err = hd["error_deg"]
        raw_err = [((rh - rf + 180.0) % 360.0) - 180.0 if math.isfinite(rf) else math.nan
                   for rh, rf in zip(raw_h, hd["heading_ref_deg"])]
        rv = [raw_err[i] for i in idx if not is_cal[i] and math.isfinite(raw_err[i])]
        raw_rms = math.sqrt(sum(x * x for x in rv) / len(rv)) if rv else math.nan
        ax.plot(idx, raw_err, ".", ms=3, color=C_OTHER,
                label="raw heading error (verification RMS %.1f deg; mostly off-scale)" % raw_rms)
        ax.plot(idx, err, ".", ms=3, color=C_IN, label="calibrated heading error")
        ax.plot(fl, [err[i] for i in fl], "x", ms=5, color=C_OUT, label="flagged outlier")
        fin = [abs(err[i]) for i in idx if not is_cal[i] and math.isfinite(err[i])]
        span = max(fin) if fin else 5.0
        ax.set_ylim(-max(3.0 * span, 1.0), max(3.0 * span, 1.0))
        title = "4. Heading error vs reference (deg)"
        if "heading_rms_deg" in rep:
            title += "\nverification rows: RMS %.3f deg, max |e| %.3f deg" % (
                rep["heading_rms_deg"], rep["heading_max_abs_deg"])
        ax.set_title(title)
        ax.set_ylabel("heading - reference (deg)")
    elif ok:
        (cx, cy), m, r = rep["center"], rep["correction"], rep["radius"]
        rr = []
        for i in idx:
            u, v = mx[i] - cx, my[i] - cy
            rr.append(math.hypot(m[0][0] * u + m[0][1] * v, m[1][0] * u + m[1][1] * v) / r)
        w = max(0.15, 6.0 * rep["radius_spread_corrected"])  # ~ +/-6 sigma of the inliers
        lo, hi = max(0.0, 1.0 - w), 1.0 + w
        ax.plot(idx, [min(max(x, lo), hi) for x in rr], ".", ms=3, color=C_IN, label="|h| / radius")
        ax.plot(fl, [min(max(rr[i], lo), hi) for i in fl], "x", ms=5, color=C_OUT, label="flagged outlier")
        ax.axhline(1.0, color=C_FIT, lw=1.5)
        ax.set_ylim(lo - 0.02, hi + 0.02)
        ax.set_ylabel("|h| / calibrated radius (clipped to the frame)")
        ax.set_title("4. Corrected radius over rows (no heading reference in this dump)")
    ax.set_xlabel("row")
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.12), ncol=2, fontsize=8, markerscale=2)
    ax.grid(alpha=0.3)

    # ---- summary line
    if ok:
        s = ("%d rows, %d calibration rows fed (decimation %d), %d used, %d outliers, coverage %.0f deg | "
             "centre (%.4g, %.4g), radius %.4g, residual RMS %.3g (%s)\nfilter %s, %s fit" % (
                 rep["n_rows"], rep["n_fed"], rep["decimation"], rep["n_used"], rep["n_outliers"],
                 rep["coverage_deg"], rep["center"][0], rep["center"][1], rep["radius"],
                 rep["residual_rms"], unit, rep["filter"], rep.get("fit", "consensus")))
        ms = rep.get("missing_sector") or {}
        if ms.get("width_deg"):
            s += " | largest gap %.0f deg from heading %.0f deg" % (ms["width_deg"], ms["start_deg"])
    else:
        s = "calibration failed (%s): %s" % (rep.get("status"), rep.get("reason", ""))
    fig.text(0.5, 0.008, s, ha="center", fontsize=9)
    fig.tight_layout(rect=(0, 0.035, 1, 0.97))
    fig.savefig(out, dpi=110)
    print(out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
