"""Point-to-line refinement of a scan match (after Censi's PLICP, ICRA 2008), compiled with numba.

PSM (:mod:`vipsm.psm`) finds the pose from range differences along the reference's bearings: it solves
large rotations well (a 1-D search over bearing shifts) but its translation step compares ranges, whose
error grows with the incidence angle, and its orientation resolution is the parabola through three
costs. A few point-to-line iterations finish the match from PSM's pose: each current point is paired
with the nearest reference point and that point's neighbour in the same segment, and the pose
minimising the weighted squared distances to those lines is solved in closed form (Gauss-Newton on the
exact point-to-line distance, rotation linearised per step). Point-to-line converges quadratically
where the surfaces are piecewise flat (Censi), so 3-6 iterations suffice.

Robustness: pairs further than ``max_dist_m`` from their line are left out, the rest weighted by a
Cauchy weight with scale ``robust_scale`` times the residuals' median absolute value (at least
``min_scale_m``: the range noise), times the beams' own weights (0: cut by the restoration).
Along directions the scene does not constrain (a corridor) the normal equations are damped towards
no change, so the step there stays where PSM left it.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .psm_kernel import bearings_of, place

#: refusal codes of :func:`refine`
OK, TOO_FEW_PAIRS, DEGENERATE = 0, 1, 2


@njit(cache=True, nogil=True, error_model="numpy")
def _pairs(rx, ry, rb, uniform, r_ok, seg, cx, cy, c_ok, x, y, th, window, max_dist, nx_out, ny_out, e_out, jt_out,
           idx_out, qx_a, qy_a, phi_a):  # pragma: no cover - compiled
    """For each usable current point placed at (x, y, th): the nearest usable reference point within
    ``window`` beams of its bearing and the neighbour of that point (same segment) nearer to it; the
    line's unit normal, the signed distance and the rotation Jacobian. Returns how many pairs.
    ``qx_a``, ``qy_a``, ``phi_a``: work space (the placed points and their bearings)."""
    n_ref = rb.size
    place(cx, cy, x, y, th, qx_a, qy_a)
    bearings_of(qx_a, qy_a, phi_a)
    b0 = rb[0]
    inv_db = (n_ref - 1) / (rb[n_ref - 1] - b0) if n_ref > 1 else 1.0
    m = 0
    for i in range(cx.size):
        if not c_ok[i]:
            continue
        qx, qy = qx_a[i], qy_a[i]
        px, py = qx - x, qy - y
        j = int(round((phi_a[i] - b0) * inv_db)) if uniform else np.searchsorted(rb, phi_a[i])
        lo, hi = max(j - window, 0), min(j + window, n_ref - 1)
        best, bj = max_dist * max_dist * 4.0, -1
        for k in range(lo, hi + 1):
            if r_ok[k]:
                d2 = (rx[k] - qx) ** 2 + (ry[k] - qy) ** 2
                if d2 < best:
                    best, bj = d2, k
        if bj < 0:
            continue
        oj = -1
        od = np.inf
        for k in (bj - 1, bj + 1):
            if 0 <= k < n_ref and r_ok[k] and seg[k] == seg[bj] and seg[k] > 0:
                d2 = (rx[k] - qx) ** 2 + (ry[k] - qy) ** 2
                if d2 < od:
                    od, oj = d2, k
        if oj < 0:
            continue
        tx, ty = rx[oj] - rx[bj], ry[oj] - ry[bj]
        tn = math.hypot(tx, ty)
        if tn <= 0.0:
            continue
        nx, ny = -ty / tn, tx / tn
        e = nx * (qx - rx[bj]) + ny * (qy - ry[bj])
        if abs(e) > max_dist:
            continue
        nx_out[m], ny_out[m], e_out[m] = nx, ny, e
        jt_out[m] = nx * (-py) + ny * px  # d e / d th
        idx_out[m] = i
        m += 1
    return m


@njit(cache=True, nogil=True, error_model="numpy")
def _solve(nx, ny, e, jt, w, m, damping):  # pragma: no cover - compiled
    """The Gauss-Newton step (dx, dy, dth) minimising sum w (e + J d)^2, damped by ``damping`` times
    the trace-normalised information; (ok, step, H's translation block, sum w)."""
    h = np.zeros((3, 3))
    g = np.zeros(3)
    sw = 0.0
    for k in range(m):
        j0, j1, j2 = nx[k], ny[k], jt[k]
        wk = w[k]
        h[0, 0] += wk * j0 * j0
        h[0, 1] += wk * j0 * j1
        h[0, 2] += wk * j0 * j2
        h[1, 1] += wk * j1 * j1
        h[1, 2] += wk * j1 * j2
        h[2, 2] += wk * j2 * j2
        g[0] += wk * j0 * e[k]
        g[1] += wk * j1 * e[k]
        g[2] += wk * j2 * e[k]
        sw += wk
    h[1, 0], h[2, 0], h[2, 1] = h[0, 1], h[0, 2], h[1, 2]
    if sw <= 0.0:
        return False, np.zeros(3), h, sw
    lam = damping * (h[0, 0] + h[1, 1]) * 0.5
    hd = h.copy()
    hd[0, 0] += lam
    hd[1, 1] += lam
    hd[2, 2] += damping * h[2, 2] + 1e-12
    det = np.linalg.det(hd)
    if not (det > 0.0 and math.isfinite(det)):
        return False, np.zeros(3), h, sw
    return True, -np.linalg.solve(hd, g), h, sw


@njit(cache=True, nogil=True, error_model="numpy")
def _reverse_pairs(rx, ry, r_ok, cx, cy, cb, c_uniform, c_ok, c_seg, x, y, th, window, max_dist, nx_out, ny_out, e_out,
                   jt_out, idx_out, m0, qx_a, qy_a, phi_a):  # pragma: no cover - compiled
    """The other direction of a symmetric match: each usable reference point, placed in the current scan's
    frame, against the line through its nearest current point and that point's neighbour. The residual is
    the same distance seen from the reference's frame, e = (R n_c) . (p - t) - n_c . c_j, so its Jacobian
    in the pose (x, y, th) is (-R n_c, (J R n_c) . (p - t)) with J the quarter turn. Appends after ``m0``
    pairs; returns the new count. ``idx_out`` holds reference indices offset by -1 - index (negative)."""
    c, s = math.cos(th), math.sin(th)
    ix, iy = -(c * x + s * y), -(-s * x + c * y)  # the inverse pose's translation
    n = _pairs(cx, cy, cb, c_uniform, c_ok, c_seg, rx, ry, r_ok, ix, iy, -th, window, max_dist,
               nx_out[m0:], ny_out[m0:], e_out[m0:], jt_out[m0:], idx_out[m0:], qx_a, qy_a, phi_a)
    for k in range(m0, m0 + n):
        i = idx_out[k]
        mx, my = c * nx_out[k] - s * ny_out[k], s * nx_out[k] + c * ny_out[k]
        px, py = rx[i] - x, ry[i] - y
        nx_out[k], ny_out[k] = -mx, -my
        jt_out[k] = -my * px + mx * py
        idx_out[k] = -1 - i
    return m0 + n


@njit(cache=True, nogil=True, error_model="numpy")
def refine(rx, ry, rb, uniform, r_ok, seg, cx, cy, c_ok, c_w, x, y, th, iterations, window, max_dist, robust_scale,
           min_scale, min_pairs, damping, degenerate_eig, stop_t, stop_r, symmetric, r_w, cb, c_uniform, c_seg
           ):  # pragma: no cover - compiled
    """Point-to-line iterations from (x, y, th); ``symmetric``: the reference's points against the current
    scan's lines too (``r_w``, ``cb``, ``c_uniform``, ``c_seg``: the reference's weights, the current scan's
    bearings, uniformity and segments). Returns (x, y, th, code, pairs, rms residual m, iterations run)."""
    n = cx.size + (rx.size if symmetric else 0)
    nx, ny, e, jt = np.empty(n), np.empty(n), np.empty(n), np.empty(n)
    idx = np.empty(n, dtype=np.int64)
    w = np.empty(n)
    nq = max(cx.size, rx.size)
    qx, qy, phi = np.empty(nq), np.empty(nq), np.empty(nq)
    m, rms, it = 0, math.nan, 0
    for it in range(1, iterations + 1):
        m = _pairs(rx, ry, rb, uniform, r_ok, seg, cx, cy, c_ok, x, y, th, window, max_dist, nx, ny, e, jt, idx,
                   qx, qy, phi)
        m_fwd = m
        if symmetric:
            m = _reverse_pairs(rx, ry, r_ok, cx, cy, cb, c_uniform, c_ok, c_seg, x, y, th, window, max_dist, nx, ny,
                               e, jt, idx, m, qx, qy, phi)
        if m_fwd < min_pairs or (symmetric and m - m_fwd < min_pairs):
            return x, y, th, TOO_FEW_PAIRS, m_fwd, rms, it
        scale = max(robust_scale * np.median(np.abs(e[:m])), min_scale)
        s2 = 0.0
        for k in range(m):
            own = c_w[idx[k]] if idx[k] >= 0 else r_w[-1 - idx[k]]
            w[k] = own / (1.0 + (e[k] / scale) ** 2)
            s2 += e[k] * e[k]
        rms = math.sqrt(s2 / m)
        ok, d, h, sw = _solve(nx, ny, e, jt, w, m, damping)
        tr = h[0, 0] + h[1, 1]
        lam_min = 0.5 * tr - math.sqrt(max(0.25 * tr * tr - (h[0, 0] * h[1, 1] - h[0, 1] * h[0, 1]), 0.0))
        if not ok or lam_min / sw < degenerate_eig:
            return x, y, th, DEGENERATE, m_fwd, rms, it
        x += d[0]
        y += d[1]
        th += d[2]
        if math.hypot(d[0], d[1]) < stop_t and abs(d[2]) < stop_r:
            break
    return x, y, th, OK, m_fwd, rms, it
