"""A rigid body has one radius (stage 6, ``Tracker._update``): a circle fitted with another tells where the
body's surface is, and its centre lies the track's radius behind that surface."""

from __future__ import annotations

import math

from vipsm.tracker import Detection, Tracker, TrackerConfig


def _fit(t_s: float, fitted_radius_m: float, true_radius_m: float = 0.5) -> tuple[Detection, tuple[float, float]]:
    """A round-ish body of ``true_radius_m`` moving along -y at 1 m/s, 3 m in front of a laser at the origin,
    seen with a circle fit of ``fitted_radius_m`` (a box's fit grows and shrinks as its corner turns into view):
    the fitted centre lies that radius behind the visible surface along the view line. Returns the detection and
    the true centre."""
    cx, cy = 3.0, 1.0 - 1.0 * t_s
    d = math.hypot(cx, cy)
    ux, uy = cx / d, cy / d
    sx, sy = cx - true_radius_m * ux, cy - true_radius_m * uy  # the visible surface
    view = math.atan2(uy, ux)
    det = Detection(sx + fitted_radius_m * ux, sy + fitted_radius_m * uy, fitted_radius_m, True, 0, 40,
                    view - 0.16, view + 0.16, evidence=True, sigma_m=0.03, behind_rad=view, laser_x_m=0.0,
                    laser_y_m=0.0, laser_theta_rad=0.0)
    return det, (cx, cy)


def test_a_bodys_fits_of_changing_radius_place_its_centre_its_own_radius_behind_the_surface() -> None:
    """Fits of 0.5 m, every third one 0.3 m (a box's corner fits smaller than its side; the first six 0.5 m, so
    the track's radius is the body's): taken as placed, the fitted centre jumps 0.2 m towards the laser on those
    scans and the filter's speed swung 0.56 m/s off; placed the track's radius behind the surface, the track
    follows the body within 0.1 m and 0.1 m/s once the filter has settled."""
    tr = Tracker(TrackerConfig())
    for k in range(25):
        t_s = 0.1 * k
        det, (cx, cy) = _fit(t_s, 0.5 if k < 6 or k % 3 else 0.3)
        tr.step(t_s, [det])
        if k >= 12:
            (t,) = tr.tracks
            assert math.hypot(t.state[0] - cx, t.state[1] - cy) < 0.1, (t_s, t.state)
            assert abs(t.speed_mps - 1.0) < 0.1, (t_s, t.speed_mps)


def test_a_round_bodys_fits_of_its_own_radius_are_taken_as_placed() -> None:
    """Fits that keep the body's radius: the centre is where each fit put it (nothing to correct)."""
    tr = Tracker(TrackerConfig())
    for k in range(20):
        det, (cx, cy) = _fit(0.1 * k, 0.5)
        tr.step(0.1 * k, [det])
    (t,) = tr.tracks
    assert math.hypot(t.state[0] - cx, t.state[1] - cy) < 0.03 and abs(t.speed_mps - 1.0) < 0.05
