"""The polar scan matcher's iteration loop, compiled with numba (``cache=True``: compiled once per
machine and kept beside this file, so only the first run after an install pays for it; the daemon
warms it up before its control loop starts, :func:`warm_up`).

The arithmetic is the one of :mod:`vipsm.psm`'s numpy stages it replaces, stage for stage:

* :func:`project_into`: the current scan placed at a pose and projected onto the reference bearings
  (ray/chord intersection or range linear in bearing, a z-buffer keeping the nearest range, pairs
  seen from behind flagged occluded);
* :func:`shift_cost`: the mean absolute range difference of the orientation search for one shift,
  over the usable beams only (a loop with early exits instead of numpy's full (2w+1) x n matrix);
* :func:`translation_step`: the weighted least-squares translation with its refusals;
* :func:`iterate`: PSM's alternation of orientation and translation steps until convergence.

Python's per-call overhead was most of the numpy version's time (about 0.8 us per tiny numpy call,
dozens per iteration); here one call runs the whole loop.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

#: refusal codes returned by :func:`iterate` (mapped to ``PsmRefusal`` by the caller)
OK, NO_VALID_SHIFT, TOO_FEW_BEAMS, DEGENERATE = 0, 1, 2, 3
_BIG = 1e6


@njit(cache=True, nogil=True)
def project_into(x_m, y_m, pair_ok, pair_w, ref_b, cos_b, sin_b, uniform, x, y, th, max_gap, line_interp,
                 min_r, max_r, out, wout, good):  # pragma: no cover - compiled
    n_ref = ref_b.size
    for j in range(n_ref):
        out[j] = np.inf
        wout[j] = 0.0
        good[j] = False
    c, s = math.cos(th), math.sin(th)
    n = x_m.size
    X = np.empty(n)
    Y = np.empty(n)
    F = np.empty(n)
    for i in range(n):
        X[i] = x + (c * x_m[i] - s * y_m[i])
        Y[i] = y + (s * x_m[i] + c * y_m[i])
        F[i] = math.atan2(Y[i], X[i])
    b0 = ref_b[0]
    inv_db = (n_ref - 1) / (ref_b[n_ref - 1] - b0) if n_ref > 1 else 1.0
    for p in range(n - 1):
        if not pair_ok[p]:
            continue
        fa, fb = F[p], F[p + 1]
        lo, hi = min(fa, fb), max(fa, fb)
        if hi - lo >= max_gap:
            continue
        if uniform:
            j0 = max(int(math.ceil((lo - b0) * inv_db)), 0)
            j1 = min(int(math.floor((hi - b0) * inv_db)), n_ref - 1)
        else:
            j0 = np.searchsorted(ref_b, lo, side="left")
            j1 = np.searchsorted(ref_b, hi, side="right") - 1
        _project_pair(X, Y, p, fa, fb, j0, j1, ref_b, cos_b, sin_b, line_interp, pair_w[p], out, wout, good)
    for j in range(n_ref):
        good[j] = good[j] and out[j] > min_r and out[j] < max_r


@njit(cache=True, nogil=True)
def _project_pair(X, Y, p, fa, fb, j0, j1, ref_b, cos_b, sin_b, line_interp, w, out, wout,
                  good):  # pragma: no cover - compiled
    xa, ya = X[p], Y[p]
    ex, ey = X[p + 1] - xa, Y[p + 1] - ya
    d = fb - fa if fb != fa else 1.0
    for j in range(j0, j1 + 1):
        if line_interp:
            den = cos_b[j] * ey - sin_b[j] * ex
            small = abs(den) < 1e-12
            rr = (xa * ey - ya * ex) / (1.0 if small else den)
            if small or rr <= 0.0:
                ra, rb = math.hypot(xa, ya), math.hypot(xa + ex, ya + ey)
                rr = ra + (ref_b[j] - fa) / d * (rb - ra)
        else:
            ra, rb = math.hypot(xa, ya), math.hypot(xa + ex, ya + ey)
            rr = ra + (ref_b[j] - fa) / d * (rb - ra)
        if rr <= out[j]:
            out[j] = rr
            wout[j] = w
            good[j] = fb > fa  # front-facing pair won the z-buffer: usable; else occluded


@njit(cache=True, nogil=True)
def shift_cost(ref_r, new_idx, new_r, shift, max_error, bound):  # pragma: no cover - compiled
    """(sum of |dr| below ``max_error``, how many, complete) comparing new beam i with reference
    beam i + shift; ``ref_r`` holds a huge value where the reference beam is unusable. Stops early
    (complete False) once the mean cannot come out at or below ``bound``: every beam still to come
    adds at least 0 to the sum and at most 1 to the count."""
    n = ref_r.size
    m = new_idx.size
    total = 0.0
    count = 0
    for k in range(m):
        r = new_idx[k] + shift
        if 0 <= r < n:
            g = abs(ref_r[r] - new_r[k])
            if g < max_error:
                total += g
                count += 1
        if k & 31 == 31 and total > bound * (count + m - 1 - k):
            return total, count, False
    return total, count, True


@njit(cache=True, nogil=True)
def _full_cost(refp, new_idx, new_r, shift, max_error, min_cnt):  # pragma: no cover - compiled
    tot, cnt, _ = shift_cost(refp, new_idx, new_r, shift, max_error, np.inf)
    return tot / cnt if cnt >= min_cnt else np.inf


@njit(cache=True, nogil=True)
def orientation_search(ref_r, ref_ok, proj_r, proj_ok, proj_w, window, max_error,
                       min_overlap_frac):  # pragma: no cover - compiled
    """Best shift (steps, sub-step refined), its cost and the cost's curvature; ok False: none valid.
    ``ref_ok``: the reference beams usable (good, weight > 0). Shifts are tried outward from 0 and a
    shift is abandoned as soon as it cannot beat the best so far; the result is the exhaustive
    search's (ties to the smaller shift), only the neighbours' costs for the curvature are computed
    in full."""
    n = ref_r.size
    w = min(window, n - 1)
    refp = np.where(ref_ok, ref_r, _BIG)
    new_idx = np.flatnonzero(proj_ok & (proj_w > 0.0))
    n_ref = int(np.count_nonzero(ref_ok))
    if n_ref == 0 or new_idx.size == 0:
        return 0.0, 0.0, 0.0, False
    new_r = proj_r[new_idx]
    min_cnt = max(1, int(math.ceil(min_overlap_frac * min(n_ref, new_idx.size))))
    best, best_k = np.inf, -1
    for step in range(2 * w + 1):
        k = w + ((step + 1) // 2 if step % 2 else -(step // 2))  # 0, +1, -1, +2, -2, ... as indices
        tot, cnt, complete = shift_cost(refp, new_idx, new_r, k - w, max_error, best)
        if complete and cnt >= min_cnt:
            c = tot / cnt
            if c < best or (c == best and k < best_k):
                best, best_k = c, k
    if best_k < 0:
        return 0.0, 0.0, 0.0, False
    return _refine(refp, new_idx, new_r, best_k, w, best, max_error, min_cnt)


@njit(cache=True, nogil=True)
def _refine(refp, new_idx, new_r, k, w, e0, max_error, min_cnt):  # pragma: no cover - compiled
    """Sub-step shift from a parabola through the best shift's cost and its neighbours'."""
    shift = float(k - w)
    curv = 0.0
    if 0 < k < 2 * w:
        em = _full_cost(refp, new_idx, new_r, k - 1 - w, max_error, min_cnt)
        ep = _full_cost(refp, new_idx, new_r, k + 1 - w, max_error, min_cnt)
        if math.isfinite(em) and math.isfinite(ep) and em > e0 and ep > e0:
            den = em + ep - 2.0 * e0
            curv = den
            if abs(den) > 1e-4:  # the original's 0.01 cm threshold, here in metres
                dd = (em - ep) / (2.0 * den)
                if abs(dd) < 1.0:
                    shift += dd
    return shift, e0, curv, True


@njit(cache=True, nogil=True)
def translation_step(ref_r, ref_ok, ref_w, cos_b, sin_b, proj_r, proj_ok, proj_w, c_m2, max_error, min_valid,
                     degenerate_eig, damping):  # pragma: no cover - compiled
    """(dx, dy, beams used, refusal code) of one weighted least-squares translation step."""
    a11 = a12 = a22 = b1 = b2 = sw = 0.0
    used = 0
    for i in range(ref_r.size):
        if not (ref_ok[i] and proj_ok[i] and proj_w[i] > 0.0):
            continue
        e = ref_r[i] - proj_r[i]
        if not abs(e) < max_error:
            continue
        ww = c_m2 / (c_m2 + e * e) * ref_w[i] * proj_w[i]
        hc, hs = cos_b[i], sin_b[i]
        a11 += ww * hc * hc
        a12 += ww * hc * hs
        a22 += ww * hs * hs
        b1 += ww * hc * e
        b2 += ww * hs * e
        sw += ww
        used += 1
    if used < min_valid:
        return 0.0, 0.0, used, TOO_FEW_BEAMS
    tr = a11 + a22
    lam_min = 0.5 * tr - math.sqrt(max(0.25 * tr * tr - (a11 * a22 - a12 * a12), 0.0))
    if sw <= 0.0 or lam_min / sw < degenerate_eig:
        return 0.0, 0.0, used, DEGENERATE
    lam = damping * sw
    a11d, a22d = a11 + lam, a22 + lam
    det = a11d * a22d - a12 * a12
    return (a22d * b1 - a12 * b2) / det, (a11d * b2 - a12 * b1) / det, used, OK


@njit(cache=True, nogil=True)
def iterate(ref_r, ref_good, ref_w, ref_b, cos_b, sin_b, uniform, dphi, cur_x, cur_y, pair_ok, pair_w,
            x, y, th, fc, ic, bc):  # pragma: no cover - compiled
    """PSM's loop from the guess (x, y, th): orientation steps on even iterations, translation steps
    on odd ones, until ``stop_count`` consecutive small steps. ``fc``/``ic``/``bc``: the float, int and
    bool parameters (see ``vipsm.psm._kernel_params``). Returns (x, y, th, iterations, converged,
    refusal, beams at the refusal, cost curvature of the last orientation step, last c_m2)."""
    (c_m2, max_error, max_error_first, c_divisor, max_gap, min_r, max_r, min_overlap, gain, stop_t, stop_r,
     degenerate_eig, damping) = fc
    change_iter, max_iter, stop_count, window_first, window, min_valid = ic
    line_interp, = bc
    ref_ok = ref_good & (ref_w > 0.0)
    n_ref = ref_b.size
    proj_r, proj_w = np.empty(n_ref), np.empty(n_ref)
    proj_ok = np.empty(n_ref, dtype=np.bool_)
    small, it, curv = 0, 0, 0.0
    last_dt, last_dth = np.inf, np.inf
    first = True
    while it < max_iter:
        if it == change_iter:
            c_m2 = c_m2 / c_divisor
        project_into(cur_x, cur_y, pair_ok, pair_w, ref_b, cos_b, sin_b, uniform, x, y, th, max_gap, line_interp,
                     min_r, max_r, proj_r, proj_w, proj_ok)
        gate = max_error_first if it < change_iter else max_error
        if it % 2 == 0:
            shift, _cost, curv, found = orientation_search(ref_r, ref_ok, proj_r, proj_ok, proj_w,
                                                           window_first if first else window, gate, min_overlap)
            first = False
            if not found:
                return x, y, th, it + 1, False, NO_VALID_SHIFT, 0, curv, c_m2
            d = gain * shift * dphi
            th = _remainder_2pi(th + d)
            last_dth = abs(d)
        else:
            dx, dy, used, code = translation_step(ref_r, ref_ok, ref_w, cos_b, sin_b, proj_r, proj_ok, proj_w, c_m2,
                                                  gate, min_valid, degenerate_eig, damping)
            if code != OK:
                return x, y, th, it + 1, False, code, used, curv, c_m2
            x += dx
            y += dy
            last_dt = math.hypot(dx, dy)
        it += 1
        if last_dt < stop_t and last_dth < stop_r:
            small += 1
            if small >= stop_count:
                return x, y, th, it, True, OK, 0, curv, c_m2
        else:
            small = 0
    return x, y, th, it, False, OK, 0, curv, c_m2


@njit(cache=True, nogil=True)
def _remainder_2pi(a):  # pragma: no cover - compiled
    """``math.remainder(a, 2 pi)``: a - n 2 pi with n the nearest integer, ties to even."""
    return a - 2.0 * math.pi * np.rint(a / (2.0 * math.pi))


# ---------------------------------------------------------------------------------------------
# preprocessing (``vipsm.psm.prepare_scan``'s median filter, segmentation and normals)


@njit(cache=True, nogil=True)
def median_filter(r, window):  # pragma: no cover - compiled
    """Window-``window`` median with the edges clamped (the ``h``-th smallest of each window)."""
    n = r.size
    h = window // 2
    out = np.empty(n)
    buf = np.empty(window)
    for i in range(n):
        for k in range(window):
            j = min(max(i + k - h, 0), n - 1)
            v = r[j]
            m = k
            while m > 0 and buf[m - 1] > v:  # insertion sort of a handful of values
                buf[m] = buf[m - 1]
                m -= 1
            buf[m] = v
        out[i] = buf[h]
    return out


@njit(cache=True, nogil=True)
def segment(ranges_m, good, dphi, jump_m, range_factor):  # pragma: no cover - compiled
    """Segment ids (1..) per beam, 0 for bad beams; the rules of ``vipsm.psm.segment_scan``."""
    n = ranges_m.size
    seg = np.zeros(n, dtype=np.int32)
    r = np.where(good, ranges_m, 0.0)
    ids = 0
    for i in range(n):
        thr = max(jump_m, range_factor * r[i] * dphi)
        if i == 0 or not good[i - 1]:
            brk = True
        else:
            jump = abs(r[i] - r[i - 1]) >= thr
            pred_ok = i >= 2 and good[i - 1] and good[i - 2]
            miss = True if i < 2 else abs(r[i] - (2.0 * r[i - 1] - r[i - 2])) >= thr
            miss_b = True
            if 1 <= i <= n - 2:
                back_ok = good[i] and good[i + 1]
                miss_b = (not back_ok) or abs(r[i - 1] - (2.0 * r[i] - r[i + 1])) >= thr
            brk = jump and (miss or not pred_ok) and miss_b
        if good[i]:
            if brk:
                ids += 1
            seg[i] = ids
    return seg


@njit(cache=True, nogil=True)
def normals(x, y, good, seg, half):  # pragma: no cover - compiled
    """Unit normals from the points ``half`` beams either side within the same run of segment ids
    (clipped at its ends); zero where a beam has no neighbour in its segment."""
    n = x.size
    nx = np.zeros(n)
    ny = np.zeros(n)
    if n < 2:
        return nx, ny
    seg_g = np.where(good, seg, 0)
    start = 0
    while start < n:
        end = start
        while end + 1 < n and seg_g[end + 1] == seg_g[start]:
            end += 1
        for i in range(start, end + 1):
            lo, hi = max(i - half, start), min(i + half, end)
            tx, ty = x[hi] - x[lo], y[hi] - y[lo]
            norm = math.hypot(tx, ty)
            if good[i] and seg[i] > 0 and hi != lo and norm > 0:
                nx[i] = -ty / norm
                ny[i] = tx / norm
        start = end + 1
    return nx, ny
