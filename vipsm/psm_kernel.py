"""The polar scan matcher's kernels, compiled with numba (``cache=True``: compiled once per machine
and kept beside this file, so only the first run after an install pays for it; the daemon loads them
before its control loop starts, ``vipsm.estimator.warm_up``).

The arithmetic is the one of the method (``vipsm.psm`` documents it), stage for stage:

* :func:`preprocess`: invalid beams, median filter, range gating, segmentation, points, pairs, normals;
* :func:`project_into`: the current scan placed at a pose and projected onto the reference bearings
  (ray/chord intersection or range linear in bearing, a z-buffer keeping the nearest range, pairs
  seen from behind flagged occluded); the points' bearings come from :func:`bearings_of`, a
  branch-free atan2 the compiler vectorises;
* :func:`orientation_search`: the mean absolute range difference for each shift, a branch-free loop
  over dense arrays (vectorised), shifts abandoned as soon as they cannot beat the best;
* :func:`translation_step`: the weighted least-squares translation with its refusals;
* :func:`iterate`: PSM's alternation of orientation and translation steps until convergence;
* :func:`match_statistics`: residual, weights and the normals' information at the matched pose.

Every kernel uses ``error_model="numpy"``: numba's Python-style checks on division stop a loop from
being vectorised; no divisor here can be zero where it is not guarded. numba does not inline one
compiled function into another unless told (``inline="always"``), which the per-pair step is.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

#: refusal codes returned by :func:`iterate` (mapped to ``PsmRefusal`` by the caller)
OK, NO_VALID_SHIFT, TOO_FEW_BEAMS, DEGENERATE = 0, 1, 2, 3
_BIG = 1e6


#: atan(t) = t * P(t^2) for 0 <= t <= tan(pi/8): least-squares coefficients of P (highest power
#: first) fitted on Chebyshev nodes; max error 2e-14 rad with the octant folding (tests/vipsm/test_psm.py)
_ATAN_P = (0.03070149028735282, -0.058771919988228345, 0.07564454610047046, -0.09078501465416303,
           0.11110393878383934, -0.14285690811416976, 0.19999999613254754, -0.3333333333087228,
           0.9999999999999747)
_P0, _P1, _P2, _P3, _P4, _P5, _P6, _P7, _P8 = _ATAN_P
_TAN_PI_8 = math.tan(math.pi / 8.0)


@njit(cache=True, nogil=True, error_model="numpy", fastmath={"contract"})
def bearings_of(X, Y, F):  # pragma: no cover - compiled
    """F[i] = atan2(Y[i], X[i]) within 2e-14 rad, branch-free so the loop is vectorised (``math.atan2``
    is a library call per point, about ten times slower): the octant folded to t in [0, 1], then to
    |t| <= tan(pi/8) with atan t = pi/4 + atan((t-1)/(t+1)), then an odd polynomial."""
    for i in range(X.size):
        x, y = X[i], Y[i]
        ax, ay = math.fabs(x), math.fabs(y)
        steep = ay > ax
        t = (ax if steep else ay) / ((ay if steep else ax) + 1e-300)
        big = t > _TAN_PI_8
        t = (t - 1.0) / (t + 1.0) if big else t
        s = t * t
        p = (((((((_P0 * s + _P1) * s + _P2) * s + _P3) * s + _P4) * s + _P5) * s + _P6) * s + _P7) * s + _P8
        a = t * p + (0.25 * math.pi if big else 0.0)
        a = 0.5 * math.pi - a if steep else a
        a = math.pi - a if x < 0.0 else a
        F[i] = -a if y < 0.0 else a


@njit(cache=True, nogil=True, error_model="numpy")
def place(x_m, y_m, x, y, th, X, Y):  # pragma: no cover - compiled
    """Points (x_m, y_m) moved to the pose (x, y, th): rotated by th, then translated."""
    c, s = math.cos(th), math.sin(th)
    for i in range(x_m.size):
        X[i] = x + (c * x_m[i] - s * y_m[i])
        Y[i] = y + (s * x_m[i] + c * y_m[i])


@njit(cache=True, nogil=True, error_model="numpy")
def project_into(x_m, y_m, pair_ok, pair_w, ref_b, cos_b, sin_b, uniform, x, y, th, max_gap, line_interp,
                 min_r, max_r, out, wout, good, X, Y, F):  # pragma: no cover - compiled
    """Fills ``out`` (range), ``wout`` (weight) and ``good`` per reference bearing; ``X``, ``Y``, ``F``:
    work space of the current scan's size (its points placed, their bearings)."""
    n_ref = ref_b.size
    out[:] = np.inf
    wout[:] = 0.0
    good[:] = False
    n = x_m.size
    place(x_m, y_m, x, y, th, X, Y)
    bearings_of(X, Y, F)
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


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
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


_CHUNK = 256  # beams summed between two checks of the early exit (a vectorised block)


@njit(cache=True, nogil=True, fastmath={"reassoc", "contract"})
def _chunk_cost(refp, newp, a, b, shift, max_error):  # pragma: no cover - compiled
    """(sum of |dr| below ``max_error``, how many) over new beams a..b-1 against reference beams
    a+shift..b-1+shift; a branch-free loop the compiler vectorises (the sum may be reassociated)."""
    r = refp[a + shift:b + shift]
    q = newp[a:b]
    total = 0.0
    count = 0.0  # a float count vectorises with the sum
    for i in range(r.size):
        g = abs(r[i] - q[i])
        ok = g < max_error
        total += g if ok else 0.0
        count += 1.0 if ok else 0.0
    return total, count


@njit(cache=True, nogil=True, error_model="numpy")
def shift_cost(refp, newp, usable_after, shift, max_error, bound):  # pragma: no cover - compiled
    """(sum of |dr| below ``max_error``, how many, complete) comparing new beam k with reference
    beam k + shift; ``refp`` holds +1e6 where the reference beam is unusable and ``newp`` -1e6 where
    the new one is, so such pairs never pass the gate. ``usable_after[k]``: usable new beams from k
    on. Stops early (complete False) once the mean cannot come out at or below ``bound``: every beam
    still to come adds at least 0 to the sum and at most 1 to the count."""
    n = refp.size
    lo, hi = max(0, -shift), min(n, n - shift)
    total = 0.0
    count = 0
    a = lo
    while a < hi:
        b = min(a + _CHUNK, hi)
        t, c = _chunk_cost(refp, newp, a, b, shift, max_error)
        total += t
        count += int(c)
        a = b
        if a < hi and total > bound * (count + usable_after[a] - usable_after[hi]):
            return total, count, False
    return total, count, True


@njit(cache=True, nogil=True, error_model="numpy")
def _full_cost(refp, newp, usable_after, shift, max_error, min_cnt):  # pragma: no cover - compiled
    tot, cnt, _ = shift_cost(refp, newp, usable_after, shift, max_error, np.inf)
    return tot / cnt if cnt >= min_cnt else np.inf


@njit(cache=True, nogil=True, error_model="numpy")
def usable_reference(ref_r, ref_ok):  # pragma: no cover - compiled
    """The reference ranges as the orientation search reads them: +1e6 where a beam is unusable."""
    return np.where(ref_ok, ref_r, _BIG)


@njit(cache=True, nogil=True, error_model="numpy")
def orientation_search(refp, n_ref, proj_r, proj_ok, proj_w, window, max_error, min_overlap_frac, newp,
                       usable_after):  # pragma: no cover - compiled
    """Best shift (steps, sub-step refined), its cost and the cost's curvature; ok False: none valid.
    ``refp``: :func:`usable_reference`, ``n_ref`` its usable beams; ``newp`` (n) and ``usable_after``
    (n + 1): work space. Shifts are tried outward from 0 and a shift is abandoned as soon as it cannot
    beat the best so far; the result is the exhaustive search's (ties to the smaller shift), only the
    neighbours' costs for the curvature are computed in full."""
    n = refp.size
    w = min(window, n - 1)
    usable_after[n] = 0  # usable new beams at index >= k
    for k in range(n - 1, -1, -1):
        ok = proj_ok[k] and proj_w[k] > 0.0
        newp[k] = proj_r[k] if ok else -_BIG
        usable_after[k] = usable_after[k + 1] + (1 if ok else 0)
    n_new = usable_after[0]
    if n_ref == 0 or n_new == 0:
        return 0.0, 0.0, 0.0, False
    min_cnt = max(1, int(math.ceil(min_overlap_frac * min(n_ref, n_new))))
    best, best_k = np.inf, -1
    for step in range(2 * w + 1):
        k = w + ((step + 1) // 2 if step % 2 else -(step // 2))  # 0, +1, -1, +2, -2, ... as indices
        tot, cnt, complete = shift_cost(refp, newp, usable_after, k - w, max_error, best)
        if complete and cnt >= min_cnt:
            c = tot / cnt
            if c < best or (c == best and k < best_k):
                best, best_k = c, k
    if best_k < 0:
        return 0.0, 0.0, 0.0, False
    return _refine(refp, newp, usable_after, best_k, w, best, max_error, min_cnt)


@njit(cache=True, nogil=True, error_model="numpy")
def _refine(refp, newp, usable_after, k, w, e0, max_error, min_cnt):  # pragma: no cover - compiled
    """Sub-step shift from a parabola through the best shift's cost and its neighbours'."""
    shift = float(k - w)
    curv = 0.0
    if 0 < k < 2 * w:
        em = _full_cost(refp, newp, usable_after, k - 1 - w, max_error, min_cnt)
        ep = _full_cost(refp, newp, usable_after, k + 1 - w, max_error, min_cnt)
        if math.isfinite(em) and math.isfinite(ep) and em > e0 and ep > e0:
            den = em + ep - 2.0 * e0
            curv = den
            if abs(den) > 1e-4:  # the original's 0.01 cm threshold, here in metres
                dd = (em - ep) / (2.0 * den)
                if abs(dd) < 1.0:
                    shift += dd
    return shift, e0, curv, True


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _robust_weight(i, ref_r, ref_ok, ref_w, proj_r, proj_ok, proj_w, c_m2, max_error):  # pragma: no cover
    """(used, residual, weight) of beam i in a translation step: both beams usable and the residual
    inside the gate; weight C / (C + e^2) times both beams' own weights."""
    if not (ref_ok[i] and proj_ok[i] and proj_w[i] > 0.0):
        return False, 0.0, 0.0
    e = ref_r[i] - proj_r[i]
    if not abs(e) < max_error:
        return False, e, 0.0
    return True, e, c_m2 / (c_m2 + e * e) * ref_w[i] * proj_w[i]


@njit(cache=True, nogil=True, error_model="numpy")
def translation_step(ref_r, ref_ok, ref_w, cos_b, sin_b, proj_r, proj_ok, proj_w, c_m2, max_error, min_valid,
                     degenerate_eig, damping):  # pragma: no cover - compiled
    """(dx, dy, beams used, refusal code) of one weighted least-squares translation step."""
    a11 = a12 = a22 = b1 = b2 = sw = 0.0
    used = 0
    for i in range(ref_r.size):
        ok, e, ww = _robust_weight(i, ref_r, ref_ok, ref_w, proj_r, proj_ok, proj_w, c_m2, max_error)
        if not ok:
            continue
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


@njit(cache=True, nogil=True, error_model="numpy")
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
    refp = usable_reference(ref_r, ref_ok)
    n_usable = int(np.count_nonzero(ref_ok))
    n_ref, n_cur = ref_b.size, cur_x.size
    proj_r, proj_w, newp = np.empty(n_ref), np.empty(n_ref), np.empty(n_ref)
    proj_ok = np.empty(n_ref, dtype=np.bool_)
    usable_after = np.empty(n_ref + 1, dtype=np.int64)
    X, Y, F = np.empty(n_cur), np.empty(n_cur), np.empty(n_cur)
    small, it, curv = 0, 0, 0.0
    last_dt, last_dth = np.inf, np.inf
    first = True
    while it < max_iter:
        if it == change_iter:
            c_m2 = c_m2 / c_divisor
        project_into(cur_x, cur_y, pair_ok, pair_w, ref_b, cos_b, sin_b, uniform, x, y, th, max_gap, line_interp,
                     min_r, max_r, proj_r, proj_w, proj_ok, X, Y, F)
        gate = max_error_first if it < change_iter else max_error
        if it % 2 == 0:
            shift, _cost, curv, found = orientation_search(refp, n_usable, proj_r, proj_ok, proj_w,
                                                           window_first if first else window, gate, min_overlap,
                                                           newp, usable_after)
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


@njit(cache=True, nogil=True, error_model="numpy")
def _remainder_2pi(a):  # pragma: no cover - compiled
    """``math.remainder(a, 2 pi)``: a - n 2 pi with n the nearest integer, ties to even."""
    return a - 2.0 * math.pi * np.rint(a / (2.0 * math.pi))


# ---------------------------------------------------------------------------------------------
# preprocessing (``vipsm.psm.prepare_scan``'s median filter, segmentation and normals)


@njit(cache=True, nogil=True, error_model="numpy")
def finite_ascending(b):  # pragma: no cover - compiled
    """Whether every value is finite and each is above the one before (one value, or none: True)."""
    for i in range(b.size):
        if not math.isfinite(b[i]) or (i > 0 and not b[i] > b[i - 1]):
            return False
    return True


@njit(cache=True, nogil=True, error_model="numpy")
def preprocess(r_raw, bearings, cos_b, sin_b, w, dphi, min_r, max_r, median_window, jump_m, range_factor, min_seg_beams,
               normal_half, tag_invalid, tag_range, tag_segment):  # pragma: no cover - compiled
    """``vipsm.psm.prepare_scan`` in one call: invalid beams tagged, median filter over the valid
    ones (invalid counts as +inf), range gating, segmentation, short segments dropped, points, pairs
    and normals. Returns (ranges, tags, segments, good, x, y, pair_ok, pair_w, normal_x, normal_y).
    ``bearings`` must be finite and ascending (ValueError)."""
    if not finite_ascending(bearings):
        raise ValueError("bearings must be finite and strictly ascending")
    n = r_raw.size
    tags = np.zeros(n, dtype=np.uint8)
    r = np.empty(n)
    for i in range(n):
        valid = math.isfinite(r_raw[i]) and r_raw[i] >= min_r
        r[i] = r_raw[i] if valid else np.inf
        if not valid:
            tags[i] = tag_invalid
    if median_window > 1 and n > 0:
        r = median_filter(r, median_window)
    for i in range(n):
        if tags[i] == 0 and not math.isfinite(r[i]):
            tags[i] = tag_invalid  # a valid beam whose window is mostly invalid
        elif tags[i] == 0 and r[i] > max_r:
            tags[i] = tag_range
    seg = segment(r, tags == 0, dphi, jump_m, range_factor)
    counts = np.bincount(seg) if n else np.zeros(1, dtype=np.int64)
    for i in range(n):
        if seg[i] > 0 and counts[seg[i]] < min_seg_beams:
            tags[i] |= tag_segment
            seg[i] = 0
    good = tags == 0
    rf = np.where(good, r, 0.0)
    x, y = rf * cos_b, rf * sin_b
    m = max(n - 1, 0)
    pair_ok = np.empty(m, dtype=np.bool_)
    pair_w = np.empty(m)
    for i in range(m):
        pair_ok[i] = good[i] and good[i + 1] and seg[i] == seg[i + 1]
        pair_w[i] = min(w[i], w[i + 1])
    nx, ny = normals(x, y, good, seg, normal_half)
    return rf, tags, seg, good, x, y, pair_ok, pair_w, nx, ny


@njit(cache=True, nogil=True, error_model="numpy")
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


@njit(cache=True, nogil=True, error_model="numpy")
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


@njit(cache=True, nogil=True, error_model="numpy")
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


# ---------------------------------------------------------------------------------------------
# the statistics of a finished match (``vipsm.psm.match_prepared``'s bookkeeping)


@njit(cache=True, nogil=True, error_model="numpy")
def match_statistics(ref_r, ref_ok, ref_w, cos_b, sin_b, normal_x, normal_y, proj_r, proj_ok, proj_w, c_m2,
                     max_error):  # pragma: no cover - compiled
    """At the matched pose, over the beams a translation step would use: (how many, mean |residual|,
    sum of weights, weighted residual variance with 2 degrees of freedom taken, and the translation
    information per unit weight i11, i12, i22 from the reference's surface normals: the weighted mean
    of g g^T, g = n / (n . u), beams hit at grazing incidence |n . u| < 0.2 left out)."""
    used = 0
    sum_abs = sw = swe2 = i11 = i12 = i22 = 0.0
    for i in range(ref_r.size):
        ok, e, w = _robust_weight(i, ref_r, ref_ok, ref_w, proj_r, proj_ok, proj_w, c_m2, max_error)
        if not ok:
            continue
        used += 1
        sum_abs += abs(e)
        sw += w
        swe2 += w * e * e
        nu = normal_x[i] * cos_b[i] + normal_y[i] * sin_b[i]
        if abs(nu) >= 0.2:
            gx, gy = normal_x[i] / nu, normal_y[i] / nu
            i11 += w * gx * gx
            i12 += w * gx * gy
            i22 += w * gy * gy
    if used == 0:
        return 0, math.nan, 0.0, 0.0, 0.0, 0.0, 0.0
    norm = 1.0 / sw if sw > 0.0 else 0.0
    return used, sum_abs / used, sw, swe2 / max(sw - 2.0, 1.0), i11 * norm, i12 * norm, i22 * norm
