"""Fig. 8/9-like pictures of a run (OpenCV)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from hil_fakes.world import (
    PAPER_SCENARIOS,
    RobotMount,
    Scenario,
)

from .metrics import RunLog

# ---------------------------------------------------------------------------------------- plots
_SCALE = 60.0  # px per metre

_MARGIN = 20


def _canvas(scale: float) -> np.ndarray:
    from hil_fakes.world.scenarios import ROOM_LENGTH_M, ROOM_WIDTH_M

    w = int(ROOM_LENGTH_M * scale + 2 * _MARGIN + 1.0 * scale)
    h = int(ROOM_WIDTH_M * scale + 2 * _MARGIN)
    return np.full((h, w, 3), 255, np.uint8)


def _to_px(x: np.ndarray | float, y: np.ndarray | float, scale: float, shape: tuple[int, ...]) -> tuple[Any, Any]:
    """World metres to pixel coordinates of a canvas (x right, y up; the room's open end at the left)."""
    from hil_fakes.world.scenarios import ROOM_WIDTH_M

    u = _MARGIN + (np.asarray(x) + 1.0) * scale
    v = _MARGIN + (ROOM_WIDTH_M / 2 - np.asarray(y)) * scale
    return u, v


def _draw_walls(img: np.ndarray, scenario: Scenario, scale: float) -> None:
    for wl in scenario.walls:
        u0, v0 = _to_px(wl.x0_m, wl.y0_m, scale, img.shape)
        u1, v1 = _to_px(wl.x1_m, wl.y1_m, scale, img.shape)
        cv2.line(img, (int(u0), int(v0)), (int(u1), int(v1)), (200, 200, 200), 3)


def _dots(
    img: np.ndarray, xs: np.ndarray, ys: np.ndarray, color: tuple[int, int, int], scale: float, r: int = 1
) -> None:
    u, v = _to_px(xs, ys, scale, img.shape)
    h, w = img.shape[:2]
    for a, b in zip(np.asarray(u, int).ravel(), np.asarray(v, int).ravel()):
        if 0 <= a < w and 0 <= b < h:
            cv2.circle(img, (int(a), int(b)), r, color, -1)


def write_plots(log: RunLog, out_dir: Path, mount: RobotMount | None = None) -> list[Path]:
    """Fig. 8 (map built along time, restored segments in red) and Fig. 9 (true vs estimated paths)."""
    mount = mount or RobotMount()
    out_dir.mkdir(parents=True, exist_ok=True)
    sc = log.scenario
    times = np.asarray(log.times_s)
    view_any = np.array([any(v) for v in log.in_view])
    if view_any.any():
        t_a, t_b = times[view_any][0], times[view_any][-1]
    else:
        t_a, t_b = times[0], times[-1]
    if sc.name in {v["name"] for v in PAPER_SCENARIOS.values()}:
        snap_t = [6.0, 8.0, 10.0, 12.0]  # the paper's Fig. 8 times
    else:
        snap_t = [t_a + (t_b - t_a) * f for f in (0.25, 0.5, 0.75, 1.0)]
    scale = _SCALE * 0.6
    panels_rows = []
    assert log.bearings_rad is not None
    for name in ("vipsm", "plain_psm"):
        m = log.methods[name]
        row = []
        for ts in snap_t:
            img = _canvas(scale)
            _draw_walls(img, sc, scale)
            last = int(np.searchsorted(times, ts, side="right"))
            for k in range(0, last, 3):
                r = log.scans[k]
                x, y, th = m.poses[k]
                lx = x + math.cos(th) * mount.laser_x_m - math.sin(th) * mount.laser_y_m
                ly = y + math.sin(th) * mount.laser_x_m + math.cos(th) * mount.laser_y_m
                a = th + mount.laser_theta_rad + log.bearings_rad
                ok = np.isfinite(r) & (r < 12.0)
                cut = np.zeros(r.shape, bool)
                for i0, i1 in m.restored[k]:
                    cut[i0:i1] = True
                px, py = lx + r * np.cos(a), ly + r * np.sin(a)
                _dots(img, px[ok & ~cut][::2], py[ok & ~cut][::2], (90, 90, 90), scale)
                _dots(img, px[ok & cut], py[ok & cut], (0, 0, 230), scale)
            tp = np.asarray(log.true_poses[:last])
            ep = np.asarray(m.poses[:last])
            _dots(img, tp[:, 0], tp[:, 1], (0, 160, 0), scale)
            _dots(img, ep[:, 0], ep[:, 1], (200, 80, 0), scale)
            k_now = max(last - 1, 0)
            for i, (ox, oy) in enumerate(log.true_obstacles[k_now]):  # the obstacles now: true (green ring)
                u, v = _to_px(ox, oy, scale, img.shape)
                rad = int(round(sc.obstacles[i].radius_m * scale))
                cv2.circle(img, (int(u), int(v)), rad, (0, 170, 0), 1, cv2.LINE_AA)
            for ox, oy in m.obstacles[k_now]:  # ... and estimated (blue cross)
                u, v = _to_px(ox, oy, scale, img.shape)
                cv2.drawMarker(img, (int(u), int(v)), (200, 80, 0), cv2.MARKER_CROSS, 9, 2)
            label = f"{'VIPSM' if name == 'vipsm' else 'plain PSM'}  t = {ts:.1f} s"
            cv2.putText(img, label, (8, 14), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (0, 0, 0), 1, cv2.LINE_AA)
            row.append(img)
        panels_rows.append(np.hstack(row))
    fig8 = np.vstack(panels_rows)
    caption = f"{sc.name}: map along time (grey), cut beams (red), true path and obstacle (green), estimated (blue)"
    cv2.putText(fig8, caption, (8, fig8.shape[0] - 6), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (0, 0, 0), 1, cv2.LINE_AA)
    p8 = out_dir / f"fig8_map_{sc.name}.png"
    cv2.imwrite(str(p8), fig8)

    fig9_scale = 100.0
    img = _canvas(fig9_scale)
    _draw_walls(img, sc, fig9_scale)
    tp = np.asarray(log.true_poses)
    _dots(img, tp[:, 0], tp[:, 1], (0, 0, 0), fig9_scale)
    for i in range(len(sc.obstacles)):
        tr = np.asarray([obs[i] for obs in log.true_obstacles])
        u, v = _to_px(tr[:, 0], tr[:, 1], fig9_scale, img.shape)
        pts = np.stack([u, v], axis=1).astype(np.int32)
        cv2.polylines(img, [pts], False, (0, 170, 0), 3, cv2.LINE_AA)
    colours = {"vipsm": (200, 80, 0), "plain_psm": (0, 0, 230)}
    for name, col in colours.items():
        m = log.methods[name]
        pts = [(x, y) for k, obs in enumerate(m.obstacles) if any(log.in_view[k]) for x, y in obs]
        if pts:
            a = np.asarray(pts)
            _dots(img, a[:, 0], a[:, 1], col, fig9_scale, 1)
    legend = [
        ("true obstacle path", (0, 170, 0)),
        ("VIPSM estimates (in view)", colours["vipsm"]),
        ("plain PSM estimates (in view)", colours["plain_psm"]),
        ("robot path", (0, 0, 0)),
    ]
    for j, (text, col) in enumerate(legend):
        cv2.putText(img, text, (10, 16 + 16 * j), cv2.FONT_HERSHEY_SIMPLEX, 0.45, col, 1, cv2.LINE_AA)
    p9 = out_dir / f"fig9_paths_{sc.name}.png"
    cv2.imwrite(str(p9), img)
    return [p8, p9]
