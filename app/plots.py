"""The run's figures with matplotlib, shared by ``eval --plots`` and ``replay --plots``.

From :class:`app.evaluation.traces.RunTrace` (one per method, VIPSM first):

* ``fig8_map_<name>``: the paper's Fig. 8, the map built along time (scan endpoints placed with each
  method's estimated pose, cut-out beams in red), the robot's path and the obstacles at four
  instants; VIPSM above plain PSM;
* ``fig9_paths_<name>``: the paper's Fig. 9, true and estimated obstacle paths, one panel per method;
* ``errors_<name>``: obstacle error and robot pose error (m, deg) against time for every method
  (only where a truth exists: a real run's log has none, and the figure says so).

Axes in metres with equal aspect, legends, titles; PNG at 150 dpi, and SVG with ``svg=True``.
"""

from __future__ import annotations

import math
import os
import re
import warnings
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from .evaluation.traces import CycleTrace, RunTrace
from .procs import process_alive

LABELS = {"vipsm": "VIPSM", "plain_psm": "plain PSM"}
DPI = 150
#: an estimate farther than this from a true obstacle is not its estimate (for the error plot)
MATCH_GATE_M = 1.0


def _plt():  # type: ignore[no-untyped-def]
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _label(trace: RunTrace) -> str:
    return LABELS.get(trace.label, trace.label)


def snapshot_times(trace: RunTrace, paper: bool) -> list[float]:
    """The paper's Fig. 8 instants (6, 8, 10, 12 s) for its scenarios, else quarters of the run."""
    t = [c.stamp_s for c in trace.cycles]
    if paper and t and t[-1] >= 12.0:
        return [6.0, 8.0, 10.0, 12.0]
    t0, t1 = t[0], t[-1]
    return [t0 + (t1 - t0) * f for f in (0.25, 0.5, 0.75, 1.0)]


def _upto(trace: RunTrace, t_s: float) -> list[CycleTrace]:
    return [c for c in trace.cycles if c.stamp_s <= t_s + 1e-9]


def _walls(ax, trace: RunTrace) -> None:  # type: ignore[no-untyped-def]
    for j, ((x0, y0), (x1, y1)) in enumerate(trace.walls_xy_m):
        ax.plot([x0, x1], [y0, y1], color="0.75", lw=2.5, zorder=1, label="walls" if j == 0 else None)


def _map_panel(ax, trace: RunTrace, t_s: float) -> None:  # type: ignore[no-untyped-def]
    cyc = _upto(trace, t_s)
    _walls(ax, trace)
    pts = [c.scan_xy_m for c in cyc[::2] if len(c.scan_xy_m)]
    if pts:
        a = np.vstack(pts)
        ax.scatter(a[:, 0], a[:, 1], s=0.3, c="0.35", lw=0, zorder=2, label="scans (estimated pose)")
    cut = [c.cut_xy_m for c in cyc if len(c.cut_xy_m)]
    if cut:
        a = np.vstack(cut)
        ax.scatter(a[:, 0], a[:, 1], s=1.5, c="tab:red", lw=0, zorder=3, label="cut-out beams")
    _, ex, ey = with_gaps(np.asarray([c.stamp_s for c in cyc]), *np.asarray([c.pose_est[:2] for c in cyc]).T)
    ax.plot(ex, ey, color="tab:blue", lw=1.2, zorder=4, label="robot, estimated")
    true = [(c.stamp_s, *c.pose_true[:2]) for c in cyc if c.pose_true is not None]
    if true:
        _, tx, ty = with_gaps(*np.asarray(true).T)
        ax.plot(tx, ty, color="tab:green", lw=1.0, ls="--", zorder=4, label="robot, true")
    _obstacles_now(ax, cyc[-1])
    ax.set_title(f"{_label(trace)}, t = {t_s:.1f} s", fontsize=9)


def _obstacles_now(ax, c: CycleTrace) -> None:  # type: ignore[no-untyped-def]
    plt = _plt()
    for j, (x, y, r) in enumerate(c.obstacles_true):
        ax.add_patch(plt.Circle((x, y), r, fill=False, ec="tab:green", lw=1.0, zorder=5,
                                label="obstacle, true" if j == 0 else None))
    for j, o in enumerate(c.obstacles_est):
        ax.add_patch(plt.Circle((o.x_m, o.y_m), o.radius_m, fill=False, ec="tab:orange", lw=1.2, zorder=6,
                                label="obstacle, estimated" if j == 0 else None))
        ax.arrow(o.x_m, o.y_m, o.vx_mps, o.vy_mps, width=0.02, color="tab:orange", zorder=6, length_includes_head=True)


def view_limits(traces: Sequence[RunTrace], margin_m: float = 0.8) -> tuple[float, float, float, float]:
    """(x0, x1, y0, y1) holding the walls, the robot's path, the obstacles and all but the farthest
    0.5 % of the scan points each way (a stray long return must not shrink the room to a dot)."""
    pts = [np.asarray(w).reshape(-1, 2) for tr in traces for w in tr.walls_xy_m]
    for tr in traces:
        pts.append(np.asarray([c.pose_est[:2] for c in tr.cycles]).reshape(-1, 2))
        pts.append(np.asarray([o[:2] for c in tr.cycles for o in c.obstacles_true]).reshape(-1, 2))
        scans = [c.scan_xy_m for c in tr.cycles[::5] if len(c.scan_xy_m)]
        if scans:
            a = np.vstack(scans)
            pts.append(np.percentile(a, [0.5, 99.5], axis=0))
    a = np.vstack([p for p in pts if len(p)])
    (x0, y0), (x1, y1) = a.min(axis=0) - margin_m, a.max(axis=0) + margin_m
    return float(x0), float(x1), float(y0), float(y1)


def _metres(ax) -> None:  # type: ignore[no-untyped-def]
    ax.set_aspect("equal", adjustable="datalim")  # the panel fills its place; the limits widen to keep 1:1
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.grid(True, lw=0.3, color="0.85")


def fig8(traces: Sequence[RunTrace], name: str, paper: bool) -> object:
    plt = _plt()
    times = snapshot_times(traces[0], paper)
    x0, x1, y0, y1 = view_limits(traces)
    fig, axes = plt.subplots(len(traces), len(times), figsize=(4.2 * len(times), 3.6 * len(traces)),
                             squeeze=False, layout="constrained")  # same limits set on each; not shared (datalim)
    for row, trace in enumerate(traces):
        for col, t_s in enumerate(times):
            _map_panel(axes[row][col], trace, t_s)
            _metres(axes[row][col])
            axes[row][col].set_xlim(x0, x1)
            axes[row][col].set_ylim(y0, y1)
            axes[row][col].label_outer()
    _figure_legend(fig, axes.ravel(), markerscale=6)
    fig.suptitle(f"{name}: the map built along time with each method's pose (cf. the paper's Fig. 8)")
    return fig


def _figure_legend(fig, axes, **kw) -> None:  # type: ignore[no-untyped-def]
    """One legend below all panels (no panel's content hidden under it), each label once."""
    seen: dict[str, object] = {}
    for ax in axes:
        for h, lab in zip(*ax.get_legend_handles_labels()):
            seen.setdefault(lab, h)
    fig.legend(list(seen.values()), list(seen), loc="outside lower center", ncol=min(len(seen), 7), fontsize=8, **kw)


def _paths_panel(ax, trace: RunTrace) -> None:  # type: ignore[no-untyped-def]
    _walls(ax, trace)
    n_true = max((len(c.obstacles_true) for c in trace.cycles), default=0)
    for i in range(n_true):
        tr = np.asarray([c.obstacles_true[i][:2] for c in trace.cycles if len(c.obstacles_true) > i])
        ax.plot(tr[:, 0], tr[:, 1], color="tab:green", lw=2.0, label="obstacle path, true" if i == 0 else None)
    by_track: dict[int, list[tuple[float, float]]] = {}
    for c in trace.cycles:
        for o in c.obstacles_est:
            by_track.setdefault(o.id, []).append((o.x_m, o.y_m))
    for j, (_tid, pts) in enumerate(sorted(by_track.items())):
        a = np.asarray(pts)
        ax.plot(a[:, 0], a[:, 1], ".", ms=2.5, label="obstacle, estimated (a colour per track)" if j == 0 else None)
    _, ex, ey = with_gaps(np.asarray([c.stamp_s for c in trace.cycles]),
                          *np.asarray([c.pose_est[:2] for c in trace.cycles]).T)
    ax.plot(ex, ey, color="k", lw=1.0, label="robot, estimated")
    ax.set_title(f"{_label(trace)}: {len(by_track)} track(s)", fontsize=10)
    _metres(ax)


def fig9(traces: Sequence[RunTrace], name: str) -> object:
    plt = _plt()
    fig, axes = plt.subplots(1, len(traces), figsize=(6.5 * len(traces), 5.0), squeeze=False,
                             layout="constrained")
    x0, x1, y0, y1 = view_limits(traces)
    for ax, trace in zip(axes[0], traces):
        _paths_panel(ax, trace)
        ax.set_xlim(x0, x1)
        ax.set_ylim(y0, y1)
        ax.label_outer()
    _figure_legend(fig, axes.ravel(), markerscale=3)
    fig.suptitle(f"{name}: true and estimated obstacle paths (cf. the paper's Fig. 9)")
    return fig


def obstacle_errors(trace: RunTrace) -> tuple[np.ndarray, np.ndarray]:
    """Per cycle, the distance from the first true obstacle to the nearest estimate (NaN: none within
    ``MATCH_GATE_M``, or no truth)."""
    t = np.asarray([c.stamp_s for c in trace.cycles])
    err = np.full(len(t), np.nan)
    for k, c in enumerate(trace.cycles):
        if c.obstacles_true and c.obstacles_est:
            x, y, _ = c.obstacles_true[0]
            d = min(math.hypot(o.x_m - x, o.y_m - y) for o in c.obstacles_est)
            err[k] = d if d <= MATCH_GATE_M else np.nan
    return t, err


def pose_errors(trace: RunTrace) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per cycle: time, position error (m) and heading error (deg) against the truth (NaN: none)."""
    rows = []
    for c in trace.cycles:
        if c.pose_true is None:
            rows.append((c.stamp_s, np.nan, np.nan))
            continue
        (ex, ey, eth), (tx, ty, tth) = c.pose_est, c.pose_true
        dth = math.degrees(math.atan2(math.sin(eth - tth), math.cos(eth - tth)))
        rows.append((c.stamp_s, math.hypot(ex - tx, ey - ty), abs(dth)))
    a = np.asarray(rows, dtype=float).reshape(-1, 3)
    return a[:, 0], a[:, 1], a[:, 2]


def fig_errors(traces: Sequence[RunTrace], name: str) -> object:
    plt = _plt()
    fig, (ax_o, ax_p, ax_h) = plt.subplots(3, 1, figsize=(8.0, 7.5), sharex=True, layout="constrained")
    has_truth = any(c.pose_true is not None for tr in traces for c in tr.cycles)
    scored = _shade_scored(ax_o, traces[0]) if traces else False
    for trace in traces:
        t, e = obstacle_errors(trace)
        ax_o.plot(*with_gaps(t, e), lw=1.2, label=_label(trace))
        t, ep, eh = pose_errors(trace)
        ax_p.plot(*with_gaps(t, ep), lw=1.2, label=_label(trace))
        ax_h.plot(*with_gaps(t, eh), lw=1.2, label=_label(trace))
    for ax, unit in ((ax_o, "obstacle error (m)"), (ax_p, "pose error (m)"), (ax_h, "heading error (deg)")):
        ax.set_ylabel(unit)
        ax.grid(True, lw=0.3, color="0.85")
        if has_truth:
            ax.legend(loc="upper left", fontsize=8)
    ax_h.set_xlabel("time (s)")
    if not has_truth:
        ax_o.text(0.5, 0.5, "no ground truth in this log (a real run): errors cannot be computed",
                  transform=ax_o.transAxes, ha="center", va="center")
    lines = [f"{name}: errors against the truth over time",
             f"gaps: no estimate within {MATCH_GATE_M:g} m of the obstacle, or cycles missing"]
    if scored:
        lines.append("shaded: the cycles the table scores (obstacle moving, in the camera's view, hit by the laser)")
    fig.suptitle("\n".join(lines), fontsize=10)
    return fig


def _shade_scored(ax, trace: RunTrace) -> bool:  # type: ignore[no-untyped-def]
    """Shades the intervals in which the first true obstacle (the one whose error is drawn) is scored by
    the evaluation's table; False when the trace does not say."""
    t = np.asarray([c.stamp_s for c in trace.cycles])
    known = [bool(c.in_view) for c in trace.cycles]
    if not any(known):
        return False
    half = 0.5 * _step(t)
    t, scored = with_gaps(t, np.asarray([bool(c.in_view) and c.in_view[0] for c in trace.cycles], float))
    for j, (i0, i1) in enumerate(runs(scored == 1.0)):  # NaN (cycles missing) ends a run
        ax.axvspan(t[i0] - half, t[i1 - 1] + half, color="tab:green", alpha=0.12, lw=0,
                   label="scored in the table" if j == 0 else None)
    return True


def _step(t: np.ndarray) -> float:
    """The usual time between cycles (the median step; 0 for fewer than two cycles)."""
    return float(np.median(np.diff(t))) if len(t) > 1 else 0.0


#: consecutive cycles farther apart than this many usual steps have cycles missing between them
GAP_STEPS = 1.5


def with_gaps(t: np.ndarray, *ys: np.ndarray) -> tuple[np.ndarray, ...]:
    """``t`` and each ``ys`` with NaN inserted wherever cycles are missing (a step longer than
    ``GAP_STEPS`` usual steps), so that a line is broken there instead of drawn across the gap."""
    t = np.asarray(t, dtype=float)
    step = _step(t)
    cut = np.flatnonzero(np.diff(t) > GAP_STEPS * step) + 1 if step > 0 else np.zeros(0, int)
    return tuple(np.insert(np.asarray(a, dtype=float), cut, np.nan) for a in (t, *ys))


def runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) index ranges of the True runs of ``mask``."""
    m = np.concatenate(([False], np.asarray(mask, bool), [False])).astype(np.int8)
    edges = np.flatnonzero(np.diff(m))
    return list(zip(edges[::2].tolist(), edges[1::2].tolist()))


def write_figures(traces: Sequence[RunTrace], out_dir: Path, name: str, *, paper: bool = False,
                  svg: bool = False) -> list[Path]:
    """Fig. 8, Fig. 9 and the error plot of a run into ``out_dir``; returns the files written. Each file
    is written under a temporary name beside it and renamed when complete (:func:`save_atomic`)."""
    plt = _plt()
    out_dir.mkdir(parents=True, exist_ok=True)
    remove_stale_partials(out_dir)
    written: list[Path] = []
    for stem, make in ((f"fig8_map_{name}", lambda: fig8(traces, name, paper)),
                       (f"fig9_paths_{name}", lambda: fig9(traces, name)),
                       (f"errors_{name}", lambda: fig_errors(traces, name))):
        fig = make()
        for ext in ("png", "svg") if svg else ("png",):
            path = out_dir / f"{stem}.{ext}"
            save_atomic(fig, path)
            written.append(path)
        plt.close(fig)
    return written


#: a figure being written: ``.<name>.<pid>.partial`` beside its final name
_PARTIAL = re.compile(r"^\.(?P<name>.+)\.(?P<pid>\d+)\.partial$")


def save_atomic(fig: object, path: Path) -> None:
    """``fig`` saved to ``path`` so that ``path`` is either the old file or the whole new one, never a
    part: written and fsynced under a temporary name in the same folder, then renamed over it."""
    tmp = path.with_name(f".{path.name}.{os.getpid()}.partial")
    try:
        with open(tmp, "wb") as f, warnings.catch_warnings():
            # the maps keep 1:1 by widening the view limits to fill their panel (adjustable="datalim"): wanted
            warnings.filterwarnings("ignore", message=r"Ignoring fixed [xy] limits to fulfill fixed data aspect")
            fig.savefig(f, format=path.suffix.lstrip("."), dpi=DPI)  # type: ignore[attr-defined]
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def remove_stale_partials(out_dir: Path) -> None:
    """Removes the temporary files of a killed figure writer (its process is gone)."""
    for p in out_dir.glob(".*.partial"):
        m = _PARTIAL.match(p.name)
        if m is not None and not process_alive(int(m["pid"])):
            p.unlink(missing_ok=True)


