#!/usr/bin/env python3
"""Convert the official geomagnetic model files into magcal's const C tables, and check them.

    cof2c.py DATA_DIR REPO_ROOT          write the generated files (see below)
    cof2c.py DATA_DIR REPO_ROOT --check  also print the double-precision reference errors

DATA_DIR holds WMM.COF, igrf14coeffs.txt, IGRF14.SHC and the official test value files
(WMM2025_TEST_VALUE_TABLE_FOR_REPORT.txt, WMM2025_FINAL_TEST_VALUES_HIGHPREC.txt,
igrf14_test_values_bgs.csv). Written under REPO_ROOT:

  src/heading/geomag_wmm2025.c             const magcal_geomag_model_t magcal_geomag_wmm2025
  src/heading/geomag_igrf14.c              const magcal_geomag_model_t magcal_geomag_igrf14
  src/heading/geomag_schmidt.c             recurrence constants of the Schmidt functions (degree 13)
  tests/support/geomag_testvalues.c/.h   every official test value, plus this script's
                                   double-precision evaluation of each point (an independent
                                   reference for the float32 library)

The double-precision synthesis below follows algorithms.md section 8 (8.2-8.6) with plain Python
floats (IEEE double). Standard library only; deterministic output (no dates, no paths).
"""
import math
import os
import sys

A_REF = 6371.2            # geomagnetic reference radius (km)
WGS84_A = 6378.137        # WGS 84 semi-major axis (km)
WGS84_F = 1.0 / 298.257223563
WGS84_E2 = WGS84_F * (2.0 - WGS84_F)
NMAX = 13                 # MAGCAL_GEOMAG_NMAX


def idx(n, m, is_h):
    """Packed index: per degree n, g_n^0 then (g_n^m, h_n^m) for m = 1..n."""
    base = n * n - 1
    if m == 0:
        return base
    return base + 2 * m - 1 + (1 if is_h else 0)


def ncoef(n):
    return n * (n + 2)


# ------------------------------------------------------------------------------------ parsing
def read_wmm(path):
    with open(path) as f:
        lines = f.read().splitlines()
    head = lines[0].split()
    epoch, name, release = float(head[0]), head[1], head[2]
    nmax = 0
    rows = []
    for ln in lines[1:]:
        t = ln.split()
        if not t or t[0].startswith("9999"):
            break
        n, m = int(t[0]), int(t[1])
        rows.append((n, m, float(t[2]), float(t[3]), float(t[4]), float(t[5])))
        nmax = max(nmax, n)
    g = [0.0] * ncoef(nmax)
    sv = [0.0] * ncoef(nmax)
    for n, m, gnm, hnm, gd, hd in rows:
        g[idx(n, m, False)] = gnm
        sv[idx(n, m, False)] = gd
        if m > 0:
            g[idx(n, m, True)] = hnm
            sv[idx(n, m, True)] = hd
        elif hnm != 0.0 or hd != 0.0:
            raise ValueError("WMM.COF: non-zero h for m = 0")
    if len(rows) != (nmax * (nmax + 3)) // 2:
        raise ValueError("WMM.COF: %d rows for degree %d" % (len(rows), nmax))
    return {"name": name, "release": release, "epochs": [epoch], "coef": [g], "sv": sv,
            "nmax": nmax}


def read_igrf_txt(path):
    with open(path) as f:
        lines = [ln for ln in f.read().splitlines() if ln.strip() and not ln.startswith("#")]
    hdr = lines[1].split()   # "g/h n m 1900.0 ... 2025.0 2025-30"
    epochs = [float(x) for x in hdr[3:-1]]
    if hdr[-1] != "2025-30":
        raise ValueError("igrf14coeffs.txt: unexpected SV column " + hdr[-1])
    ne = len(epochs)
    coef = [[0.0] * ncoef(NMAX) for _ in range(ne)]
    sv = [0.0] * ncoef(NMAX)
    count = 0
    for ln in lines[2:]:
        t = ln.split()
        gh, n, m = t[0], int(t[1]), int(t[2])
        vals = [float(x) for x in t[3:]]
        if len(vals) != ne + 1:
            raise ValueError("igrf14coeffs.txt: bad row " + ln)
        k = idx(n, m, gh == "h")
        for e in range(ne):
            coef[e][k] = vals[e]
        sv[k] = vals[ne]
        count += 1
    if count != ncoef(NMAX):
        raise ValueError("igrf14coeffs.txt: %d rows" % count)
    return {"name": "IGRF-14", "epochs": epochs, "coef": coef, "sv": sv, "nmax": NMAX}


def read_igrf_shc(path):
    with open(path) as f:
        lines = [ln for ln in f.read().splitlines() if ln.strip() and not ln.startswith("#")]
    par = lines[0].split()
    nmin, nmax, ne = int(par[0]), int(par[1]), int(par[2])
    epochs = [float(x) for x in lines[1].split()]
    if nmin != 1 or len(epochs) != ne:
        raise ValueError("IGRF14.SHC: bad header")
    coef = [[0.0] * ncoef(nmax) for _ in range(ne)]
    seen = set()
    for ln in lines[2:]:
        t = ln.split()
        n, m = int(t[0]), int(t[1])
        is_h = (m > 0 and (n, m) in seen)
        seen.add((n, m))
        k = idx(n, m, is_h)
        for e in range(ne):
            coef[e][k] = float(t[2 + e])
    return epochs, coef


def cross_check_igrf(txt, shc_path):
    """IGRF14.SHC must equal igrf14coeffs.txt at every epoch; its 2030 column = 2025 + 5 SV."""
    ep, coef = read_igrf_shc(shc_path)
    worst = 0.0
    for e, t in enumerate(ep):
        if t in txt["epochs"]:
            ref = txt["coef"][txt["epochs"].index(t)]
        else:
            last = txt["coef"][-1]
            ref = [last[k] + (t - txt["epochs"][-1]) * txt["sv"][k] for k in range(len(last))]
        worst = max(worst, max(abs(a - b) for a, b in zip(coef[e], ref)))
    if worst > 1e-9:
        raise ValueError("IGRF14.SHC and igrf14coeffs.txt differ by %g nT" % worst)
    return len(ep)


# ----------------------------------------------------------------- double-precision reference
def coeffs_at(model, t):
    """(g, gdot) packed at decimal year t: interpolation between epochs, SV after the last."""
    ep = model["epochs"]
    if t >= ep[-1]:
        base = model["coef"][-1]
        return ([base[k] + (t - ep[-1]) * model["sv"][k] for k in range(len(base))],
                list(model["sv"]))
    e = max(i for i in range(len(ep)) if ep[i] <= t)
    step = ep[e + 1] - ep[e]
    w = (t - ep[e]) / step
    c0, c1 = model["coef"][e], model["coef"][e + 1]
    return ([c0[k] + w * (c1[k] - c0[k]) for k in range(len(c0))],
            [(c1[k] - c0[k]) / step for k in range(len(c0))])


def synth_geocentric(model, t, mu, nu, lon_deg, r):
    """X', Y', Z' and their rates at sin(lat') = mu, cos(lat') = nu, radius r (algorithms.md 8.4-8.5)."""
    g, gd = coeffs_at(model, t)
    nmax = model["nmax"]
    lam = math.radians(lon_deg)
    out = [0.0] * 6
    for m in range(nmax + 1):
        cm, sm = math.cos(m * lam), math.sin(m * lam)
        # u = P (m = 0) or Q = P / nu (m >= 1); same recurrence in n.
        if m == 0:
            umm, dmm = 1.0, 0.0
        else:
            umm, dmm = 1.0, mu          # Q_1^1 = 1, dP_1^1 = mu
            for k in range(2, m + 1):
                s = math.sqrt((2.0 * k - 1.0) / (2.0 * k))
                pprev = nu * umm
                dmm = s * (nu * dmm + mu * pprev)
                umm = s * nu * umm
        w = 1.0 if m == 0 else nu
        u1, u2, d1, d2 = umm, 0.0, dmm, 0.0
        for n in range(m, nmax + 1):
            if n > m:
                a = (2.0 * n - 1.0) / math.sqrt(n * n - m * m)
                b = math.sqrt(((n - 1.0) ** 2 - m * m) / (n * n - m * m))
                u = a * mu * u1 - b * u2
                d = a * (mu * d1 - nu * w * u1) - b * d2
                u1, u2, d1, d2 = u, u1, d, d1
            if n == 0:
                continue
            u, d = u1, d1
            p = w * u
            rn = (A_REF / r) ** (n + 2)
            gi = idx(n, m, False)
            for c, (gg, hh) in enumerate(((g[gi], g[gi + 1] if m else 0.0),
                                          (gd[gi], gd[gi + 1] if m else 0.0))):
                gc = gg * cm + hh * sm
                out[3 * c + 0] += rn * gc * d
                out[3 * c + 1] += rn * m * (gg * sm - hh * cm) * u
                out[3 * c + 2] -= (n + 1) * rn * gc * p
    return out


def eval_geodetic(model, t, lat, lon, h):
    """Geodetic elements in double (algorithms.md 8.2 and 8.6)."""
    phi = math.radians(lat)
    sp, cp = math.sin(phi), math.cos(phi)
    if abs(lat) == 90.0:
        cp = 0.0
    rc = WGS84_A / math.sqrt(1.0 - WGS84_E2 * sp * sp)
    p = (rc + h) * cp
    z = (rc * (1.0 - WGS84_E2) + h) * sp
    r = math.hypot(p, z)
    mu, nu = z / r, p / r
    v = synth_geocentric(model, t, mu, nu, lon, r)
    psi = math.atan2(mu, nu) - phi
    cs, sn = math.cos(psi), math.sin(psi)
    x = v[0] * cs - v[2] * sn
    y = v[1]
    zz = v[0] * sn + v[2] * cs
    xd = v[3] * cs - v[5] * sn
    yd = v[4]
    zd = v[3] * sn + v[5] * cs
    hh = math.hypot(x, y)
    f = math.hypot(hh, zz)
    d = math.degrees(math.atan2(y, x))
    i = math.degrees(math.atan2(zz, hh))
    hd = (x * xd + y * yd) / hh
    fd = (x * xd + y * yd + zz * zd) / f
    dd = math.degrees((x * yd - y * xd) / (hh * hh))
    idt = math.degrees((hh * zd - zz * hd) / (f * f))
    if lat > 55.0:
        gv = d - lon
    elif lat < -55.0:
        gv = d + lon
    else:
        gv = float("nan")
    if gv == gv:
        gv = math.fmod(gv, 360.0)
        gv = gv - 360.0 if gv > 180.0 else (gv + 360.0 if gv <= -180.0 else gv)
    return {"x": x, "y": y, "z": zz, "h": hh, "f": f, "decl": d, "incl": i, "gv": gv,
            "xdot": xd, "ydot": yd, "zdot": zd, "hdot": hd, "fdot": fd, "ddot": dd, "idot": idt}


# ----------------------------------------------------------------------------- test values
def read_table(path):
    rows = []
    with open(path) as f:
        for ln in f:
            if ln.strip() and not ln.lstrip().startswith("#"):
                rows.append([float(x) for x in ln.split()])
    return rows


def wmm_report_rows(path):
    out = []
    for r in read_table(path):
        (t, h, lat, lon, x, y, z, hh, f, i, d, gv, xd, yd, zd, hd, fd, idt, dd) = r
        out.append({"year": t, "height": h, "lat": lat, "lon": lon, "x": x, "y": y, "z": z,
                    "h": hh, "f": f, "incl": i, "decl": d, "gv": gv, "xdot": xd, "ydot": yd,
                    "zdot": zd, "hdot": hd, "fdot": fd, "idot": idt, "ddot": dd})
    return out


def wmm_highprec_rows(path):
    out = []
    for r in read_table(path):
        (t, h, lat, lon, d, i, hh, x, y, z, f, dd, idt, hd, xd, yd, zd, fd) = r
        out.append({"year": t, "height": h, "lat": lat, "lon": lon, "x": x, "y": y, "z": z,
                    "h": hh, "f": f, "incl": i, "decl": d, "gv": float("nan"), "xdot": xd,
                    "ydot": yd, "zdot": zd, "hdot": hd, "fdot": fd, "idot": idt, "ddot": dd})
    return out


def igrf_bgs_rows(path):
    out = []
    with open(path) as f:
        lines = [ln.strip() for ln in f if ln.strip() and not ln.startswith("#")]
    for ln in lines[1:]:
        t, colat, lon, r, x, y, z = [float(v) for v in ln.split(",")]
        out.append({"year": t, "colat": colat, "lon": lon, "r": r, "x": x, "y": y, "z": z})
    return out


# Extra points without official values (poles, height and date limits, IGRF epochs and SV):
# the float32 library is compared with this script's double evaluation there.
# (model, year, height km, lat, lon)
EXTRA_POINTS = [
    ("wmm", 2026.0, 0.0, 90.0, 0.0),
    ("wmm", 2026.0, 0.0, 90.0, 120.0),
    ("wmm", 2026.0, 0.0, -90.0, -45.0),
    ("wmm", 2029.999, 850.0, 89.9999, 10.0),
    ("wmm", 2025.0, -1.0, -89.5, 359.5),
    ("wmm", 2028.7, 12.3, 45.5, -359.0),
    ("wmm", 2030.0, 0.3, -33.9, 18.4),
    ("igrf", 1900.0, 0.0, -30.0, 20.0),
    ("igrf", 1995.5, 0.0, 51.5, -1.3),
    ("igrf", 2000.0, 0.0, 60.0, 200.0),
    ("igrf", 2012.25, 0.0, 0.0, 0.0),
    ("igrf", 2019.999, 2.0, -45.0, 170.0),
    ("igrf", 2027.3, 0.5, 35.7, 139.7),
    ("igrf", 2030.0, 100.0, -80.0, 240.0),
    ("igrf", 2026.0, 0.0, 90.0, 0.0),
]


def extra_rows(models):
    out = []
    nan = float("nan")
    for name, t, h, lat, lon in EXTRA_POINTS:
        r = {"model": 0 if name == "wmm" else 1, "year": t, "height": h, "lat": lat, "lon": lon}
        for k in TV_FIELDS[4:]:
            r[k] = nan
        r["ref"] = eval_geodetic(models[name], t, lat, lon, h)
        out.append(r)
    return out


def igrf_bgs_ref(model, row):
    th = math.radians(row["colat"])
    mu, nu = math.cos(th), math.sin(th)
    v = synth_geocentric(model, row["year"], mu, nu, row["lon"], row["r"])
    return {"x": v[0], "y": v[1], "z": v[2]}


# ------------------------------------------------------------------------------- C emission
GEN_NOTE = ("/* GENERATED by tools/geomag/cof2c.py from %s -- do not edit.\n"
            " * %s */\n")


def cfloat(v):
    s = repr(float(v))
    if s == "nan":
        return "NAN"
    if "e" not in s and "." not in s:
        s += ".0"
    return s + "f"


def cdouble(v):
    s = repr(float(v))
    if s == "nan":
        return "NAN"
    if "e" not in s and "." not in s:
        s += ".0"
    return s


def emit_array(ctype, name, values, fmt, per_line=6):
    out = ["static const %s %s[%d] = {" % (ctype, name, len(values))]
    for i in range(0, len(values), per_line):
        out.append("    " + ", ".join(fmt(v) for v in values[i:i + per_line]) + ",")
    out.append("};")
    return "\n".join(out)


def trimmed_degree(c):
    n = int(round(math.sqrt(len(c) + 1))) - 1
    while n > 0 and all(v == 0.0 for v in c[ncoef(n - 1):ncoef(n)]):
        n -= 1
    return n


def emit_model(model, sym, source, prov, valid, heights):
    packed, starts, nmaxes = [], [], []
    for c in model["coef"]:
        n = trimmed_degree(c)
        starts.append(len(packed))
        nmaxes.append(n)
        packed.extend(c[:ncoef(n)])
    sv_n = trimmed_degree(model["sv"])
    ep = model["epochs"]
    step = (ep[1] - ep[0]) if len(ep) > 1 else 0.0
    for i in range(1, len(ep)):
        if abs(ep[i] - ep[i - 1] - step) > 1e-9:
            raise ValueError("epochs not evenly spaced")
    body = [GEN_NOTE % (source, prov),
            "#include \"magcal/geomag.h\"\n",
            "#if MAGCAL_CFG_ENABLE_GEOMAG /* config.h feature switch */\n",
            emit_array("float", sym + "_coef", packed, cfloat), "",
            emit_array("uint16_t", sym + "_start", starts, str, 10), "",
            emit_array("uint8_t", sym + "_nmax", nmaxes, str, 14), "",
            emit_array("float", sym + "_sv", model["sv"][:ncoef(sv_n)], cfloat), "",
            "const magcal_geomag_model_t magcal_geomag_%s = {" % sym,
            "    \"%s\"," % model["name"],
            "    %s_coef," % sym, "    %s_start," % sym, "    %s_nmax," % sym, "    %s_sv," % sym,
            "    %s, /* first epoch */" % cfloat(ep[0]),
            "    %s, /* epoch step (years) */" % cfloat(step),
            "    %s, /* valid from */" % cfloat(valid[0]),
            "    %s, /* valid to */" % cfloat(valid[1]),
            "    %s, /* height min (km) */" % cfloat(heights[0]),
            "    %s, /* height max (km) */" % cfloat(heights[1]),
            "    %du, /* epochs */" % len(ep),
            "    %du, /* nmax */" % max(nmaxes),
            "    %du  /* sv nmax */" % sv_n,
            "};", "#endif /* MAGCAL_CFG_ENABLE_GEOMAG */", ""]
    return "\n".join(body)


def emit_schmidt():
    """Recurrence constants for the (n, m) triangle, n = 1..NMAX, 0 <= m < n, row-major by n:
    a = (2n-1)/sqrt(n^2-m^2), b = sqrt(((n-1)^2-m^2)/(n^2-m^2)); and s_n = sqrt((2n-1)/(2n))."""
    a, b = [], []
    for n in range(1, NMAX + 1):
        for m in range(0, n):
            a.append((2.0 * n - 1.0) / math.sqrt(n * n - m * m))
            b.append(math.sqrt(((n - 1.0) ** 2 - m * m) / (n * n - m * m)))
    s = [0.0, 1.0] + [math.sqrt((2.0 * n - 1.0) / (2.0 * n)) for n in range(2, NMAX + 1)]
    txt = [GEN_NOTE % ("the Schmidt recurrences of algorithms.md 8.4", "Degree 13 triangle."),
           "#include \"geomag_internal.h\"\n",
           "#if MAGCAL_CFG_ENABLE_GEOMAG /* config.h feature switch */\n",
           "/* a[n(n-1)/2 + m] = (2n-1)/sqrt(n^2-m^2), n = 1..13, m = 0..n-1 */",
           emit_array("float", "a_tab", a, cfloat).replace("static ", ""), "",
           "/* b[n(n-1)/2 + m] = sqrt(((n-1)^2-m^2)/(n^2-m^2)) */",
           emit_array("float", "b_tab", b, cfloat).replace("static ", ""), "",
           "/* s[n] = sqrt((2n-1)/(2n)) for n >= 2 (s[0] unused, s[1] = 1) */",
           emit_array("float", "s_tab", s, cfloat).replace("static ", ""), "",
           "#endif /* MAGCAL_CFG_ENABLE_GEOMAG */", ""]
    out = "\n".join(txt)
    out = out.replace("const float a_tab", "const float magcal_geomag_schmidt_a")
    out = out.replace("const float b_tab", "const float magcal_geomag_schmidt_b")
    out = out.replace("const float s_tab", "const float magcal_geomag_schmidt_s")
    return out


TV_FIELDS = ["year", "height", "lat", "lon", "x", "y", "z", "h", "f", "decl", "incl", "gv",
             "xdot", "ydot", "zdot", "hdot", "fdot", "ddot", "idot"]


def emit_testvalues(report, highprec, bgs, extra):
    h = ["/* GENERATED by tools/geomag/cof2c.py -- do not edit.",
         " * Official WMM2025 / IGRF-14 test values (see docs/geomag.md for provenance) and, for",
         " * each point, cof2c.py's double-precision evaluation (ref) as an independent reference. */",
         "#ifndef GEOMAG_TESTVALUES_H", "#define GEOMAG_TESTVALUES_H", "",
         "#include <stddef.h>", "",
         "/** One geodetic test point: inputs, official values, double reference. */",
         "typedef struct {",
         "    double year, height_km, lat_deg, lon_deg;",
         "    /* official: nT, deg, nT/yr, deg/yr; gv is NAN where the file has none */",
         "    double x, y, z, h, f, decl, incl, gv, xdot, ydot, zdot, hdot, fdot, ddot, idot;",
         "    /* cof2c.py double-precision evaluation, same order */",
         "    double rx, ry, rz, rh, rf, rdecl, rincl, rgv, rxdot, rydot, rzdot, rhdot, rfdot,",
         "        rddot, ridot;",
         "    int model; /* 0: WMM2025, 1: IGRF-14 */",
         "} geomag_tv_t;", "",
         "/** One IGRF-14 BGS point: geocentric inputs and X', Y', Z' (nT), official and ref. */",
         "typedef struct {",
         "    double year, colat_deg, lon_deg, radius_km;",
         "    double x, y, z;",
         "    double rx, ry, rz;",
         "} geomag_tv_gc_t;", "",
         "extern const geomag_tv_t geomag_tv_wmm_report[%d];" % len(report),
         "extern const geomag_tv_t geomag_tv_wmm_highprec[%d];" % len(highprec),
         "extern const geomag_tv_gc_t geomag_tv_igrf_bgs[%d];" % len(bgs),
         "/* no official values (all NAN): poles, limits, IGRF epochs; compare with the ref */",
         "extern const geomag_tv_t geomag_tv_extra[%d];" % len(extra),
         "#define GEOMAG_TV_EXTRA_N %du" % len(extra),
         "#define GEOMAG_TV_WMM_REPORT_N %du" % len(report),
         "#define GEOMAG_TV_WMM_HIGHPREC_N %du" % len(highprec),
         "#define GEOMAG_TV_IGRF_BGS_N %du" % len(bgs), "",
         "#endif", ""]
    c = ["/* GENERATED by tools/geomag/cof2c.py -- do not edit. */",
         "#include <math.h>", "", "#include \"geomag_testvalues.h\"", ""]

    def geo_table(name, rows):
        c.append("const geomag_tv_t %s[%d] = {" % (name, len(rows)))
        for r in rows:
            vals = [r[k] for k in TV_FIELDS] + [r["ref"][k] for k in TV_FIELDS[4:]]
            c.append("    {" + ", ".join(cdouble(v) for v in vals) + ", %d}," % r.get("model", 0))
        c.append("};")
        c.append("")

    geo_table("geomag_tv_wmm_report", report)
    geo_table("geomag_tv_wmm_highprec", highprec)
    geo_table("geomag_tv_extra", extra)
    c.append("const geomag_tv_gc_t geomag_tv_igrf_bgs[%d] = {" % len(bgs))
    for r in bgs:
        vals = [r["year"], r["colat"], r["lon"], r["r"], r["x"], r["y"], r["z"],
                r["ref"]["x"], r["ref"]["y"], r["ref"]["z"]]
        c.append("    {" + ", ".join(cdouble(v) for v in vals) + "},")
    c.append("};")
    c.append("")
    return "\n".join(h), "\n".join(c)


def write(path, text):
    os.makedirs(os.path.dirname(path), exist_ok=True)
    with open(path, "w", newline="\n") as f:
        f.write(text)


def main(argv):
    if len(argv) < 3:
        sys.stderr.write(__doc__)
        return 2
    data, root = argv[1], argv[2]
    check = "--check" in argv[3:]
    wmm = read_wmm(os.path.join(data, "WMM.COF"))
    igrf = read_igrf_txt(os.path.join(data, "igrf14coeffs.txt"))
    n_shc = cross_check_igrf(igrf, os.path.join(data, "IGRF14.SHC"))

    write(os.path.join(root, "src", "heading", "geomag_wmm2025.c"), emit_model(
        wmm, "wmm2025", "WMM.COF (%s %.1f, released %s)" % (wmm["name"], wmm["epochs"][0],
                                                            wmm["release"]),
        "NOAA NCEI / BGS World Magnetic Model, public domain; see docs/geomag.md.",
        (2025.0, 2030.0), (-1.0, 850.0)))
    write(os.path.join(root, "src", "heading", "geomag_igrf14.c"), emit_model(
        igrf, "igrf14", "igrf14coeffs.txt (IGRF-14, cross-checked against IGRF14.SHC)",
        "IAGA Division V WG V-MOD, freely distributed; see docs/geomag.md.",
        (1900.0, 2030.0), (-1.0, 850.0)))
    write(os.path.join(root, "src", "heading", "geomag_schmidt.c"), emit_schmidt())

    report = wmm_report_rows(os.path.join(data, "WMM2025_TEST_VALUE_TABLE_FOR_REPORT.txt"))
    highprec = wmm_highprec_rows(os.path.join(data, "WMM2025_FINAL_TEST_VALUES_HIGHPREC.txt"))
    bgs = igrf_bgs_rows(os.path.join(data, "igrf14_test_values_bgs.csv"))
    for r in report + highprec:
        r["ref"] = eval_geodetic(wmm, r["year"], r["lat"], r["lon"], r["height"])
    for r in bgs:
        r["ref"] = igrf_bgs_ref(igrf, r)
    extra = extra_rows({"wmm": wmm, "igrf": igrf})
    hdr, src = emit_testvalues(report, highprec, bgs, extra)
    write(os.path.join(root, "tests", "support", "geomag_testvalues.h"), hdr)
    write(os.path.join(root, "tests", "support", "geomag_testvalues.c"), src)

    if check:
        print("IGRF14.SHC == igrf14coeffs.txt at all %d SHC epochs" % n_shc)

        def worst(rows, keys):
            res = {}
            for k in keys:
                errs = [abs(r["ref"][k] - r[k]) for r in rows if r[k] == r[k]]
                res[k] = max(errs) if errs else float("nan")
            return res

        comp = ["x", "y", "z", "h", "f"]
        ang = ["decl", "incl", "gv"]
        rates = ["xdot", "ydot", "zdot", "hdot", "fdot", "ddot", "idot"]
        for name, rows in (("WMM2025 report table (12)", report),
                           ("WMM2025 high-precision (%d)" % len(highprec), highprec)):
            w = worst(rows, comp + ang + rates)
            print("%s, double reference - official:" % name)
            print("   nT   : " + "  ".join("%s %.4f" % (k, w[k]) for k in comp))
            print("   deg  : " + "  ".join("%s %.4f" % (k, w[k]) for k in ang))
            print("   rates: " + "  ".join("%s %.4f" % (k, w[k]) for k in rates))
        w = worst(bgs, ["x", "y", "z"])
        print("IGRF-14 BGS (%d), double reference - official: X' %.4f  Y' %.4f  Z' %.4f nT"
              % (len(bgs), w["x"], w["y"], w["z"]))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
