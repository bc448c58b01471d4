#!/usr/bin/python3
"""Double-precision (numpy) reference for the 2-D ellipse fit (algorithms.md 2.1-2.4).

Regenerates, bit for bit, the synthetic rings of tests/support/test_util.c (xorshift32 +
Box-Muller, float32 rounding of T, b and the samples), fits them with numpy.linalg.lstsq on
centred and scaled data, and prints the geometry and heading offsets used as golden values in
tests/test_ellipse.c. Run with Debian's interpreter:  /usr/bin/python3 tools/ref/ellipse_ref.py
"""
import numpy as np

f32 = np.float32


def xorshift_uniform(state):
    x = state[0] if state[0] else 0x12345678
    x ^= (x << 13) & 0xFFFFFFFF
    x ^= x >> 17
    x ^= (x << 5) & 0xFFFFFFFF
    state[0] = x
    return x / 4294967296.0


def rand_normal(state):
    u1 = xorshift_uniform(state)
    u2 = xorshift_uniform(state)
    u1 = max(u1, 1e-300)
    return np.sqrt(-2.0 * np.log(u1)) * np.cos(2.0 * np.pi * u2)


def make_dist(h0, kx, ky, phis_deg, phip_deg, bx, by):
    """T = R(phis) diag(kx, ky) R(phip), stored in float32 like test_distortion_t."""
    r = lambda a: np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    t = r(np.radians(phis_deg)) @ np.diag([kx, ky]) @ r(np.radians(phip_deg))
    return dict(h0=float(f32(h0)), t=t.astype(f32).astype(float), bx=float(f32(bx)), by=float(f32(by)))


def make_ring(d, n, start_deg, arc_deg, sigma, seed):
    state = [seed if seed else 1]
    pts = np.zeros((n, 2))
    psi = np.zeros(n)
    for k in range(n):
        p = start_deg + arc_deg * k / n
        ps = np.radians(p)
        hx, hy = -d['h0'] * np.sin(ps), d['h0'] * np.cos(ps)
        nx = sigma * rand_normal(state) if sigma > 0 else 0.0
        ny = sigma * rand_normal(state) if sigma > 0 else 0.0
        t = d['t']
        pts[k, 0] = f32(t[0, 0] * hx + t[0, 1] * hy + d['bx'] + nx)
        pts[k, 1] = f32(t[1, 0] * hx + t[1, 1] * hy + d['by'] + ny)
        psi[k] = p % 360.0
    return pts, psi


def fit(pts):
    """Centred + scaled least squares (numpy lstsq, i.e. QR/SVD on W, not normal equations)."""
    m = pts.mean(axis=0)
    s = np.max(np.hypot(*(pts - m).T))
    x, y = ((pts - m) / s).T
    w = np.c_[x * y, y * y, x, y, np.ones_like(x)]
    a, b, c, d, e = np.linalg.lstsq(w, -x * x, rcond=None)[0]
    delta = 4 * b - a * a
    if delta <= 0:
        return dict(delta=delta)
    x0, y0 = (a * d - 2 * b * c) / delta, (a * c - 2 * d) / delta
    k = -(e + (c * x0 + d * y0) / 2)
    h = np.sqrt((1 - b) ** 2 + a * a)
    l1, l2 = (1 + b) / 2 + h / 2, (1 + b) / 2 - h / 2
    return dict(cx=m[0] + s * x0, cy=m[1] + s * y0, r1=s * np.sqrt(k / l1), r2=s * np.sqrt(k / l2),
                theta=0.5 * np.arctan2(a, 1 - b), delta=delta)


def heading_offset(fitres, pts, psi, form):
    th, r1, r2 = fitres['theta'], fitres['r1'], fitres['r2']
    c, s = np.cos(th), np.sin(th)
    rot = np.array([[c, -s], [s, c]])
    q = rot @ np.diag([1 / r1 ** 2, 1 / r2 ** 2]) @ rot.T
    if form == 'sym':
        m = rot @ np.diag([1 / r1, 1 / r2]) @ rot.T
    else:  # upper triangular, M^T M = Q
        m = np.linalg.cholesky(q).T
    u = pts - [fitres['cx'], fitres['cy']]
    h = u @ m.T
    meas = np.degrees(np.arctan2(-h[:, 0], h[:, 1]))
    e = (meas - psi + 180.0) % 360.0 - 180.0
    return e.mean(), e.max() - e.min()


if __name__ == '__main__':
    cases = [
        ('alg. 2.3 example, 400 pts, noise 1e-4, seed 11', (0.35, 1.15, 0.80, 25.0, -10.0, 0.42, -0.27), 400, 0, 360, 1e-4, 11),
        ('alg. 2.5 offset/radius 20, noise 2, seed 21', (300.0, 1, 1, 0, 0, 6000.0, -5000.0), 2000, 0, 360, 2.0, 21),
        ('alg. 2.5 offset/radius 5 at 25000 counts, seed 22', (5000.0, 1, 1, 0, 0, 20000.0, -15000.0), 2000, 0, 360, 2.0, 22),
        ('60 deg arc, noise 0.01, seed 31', (0.35, 1.15, 0.80, 25.0, -10.0, 0.42, -0.27), 200, 30, 60, 0.01, 31),
    ]
    for name, dist, n, start, arc, sigma, seed in cases:
        pts, psi = make_ring(make_dist(*dist), n, start, arc, sigma, seed)
        r = fit(pts)
        print(name)
        if r['delta'] <= 0:
            print('  not an ellipse: 4B-A^2 %.6g' % r['delta'])
            continue
        print('  centre (%.9g, %.9g)  r1 %.9g  r2 %.9g  theta %.7f deg  4B-A^2 %.6g'
              % (r['cx'], r['cy'], r['r1'], r['r2'], np.degrees(r['theta']), r['delta']))
        if arc == 360 and dist[1] != dist[2]:
            for form in ('sym', 'tri'):
                mean, ptp = heading_offset(r, pts, psi, form)
                print('  heading offset %s: mean %.5f deg, peak-to-peak %.5f deg' % (form, mean, ptp))
