"""Obstacle position from its scan points, and a constant-velocity tracker for several obstacles.

Tracks are born from moving-body candidates (:mod:`vipsm.bodies`) and reported only once
**confirmed**: seen in ``CONFIRM_HITS`` cycles, with motion evidence (free-space violation or camera)
in ``CONFIRM_EVIDENCE`` of them, and displaced at least ``confirm_displacement_m`` from where it was
born. Furniture never moves, so a camera flow error or a stray return on it never confirms. A track
dies after ``max_missed_s`` without a detection (``tentative_max_missed_s`` before it is confirmed, and
unconfirmed at ``tentative_max_age_s``), or at once when a beam of the current scan passes through
where it should be (its space is seen free). At most ``max_tracks`` live at once (the least
supported are dropped first), so the cost is bounded however cluttered the room.

The filter is an interacting-multiple-model (IMM) filter of two constant-velocity models, one with
the small process noise of steady walking (0.2 m/s^2: a walker's speed wanders by about 0.1 m/s over a
few seconds) and one with that of a manoeuvre (2 m/s^2: starting, stopping, turning, stepping aside
take about half a second); the mode probabilities follow which one explains the detections. One
model would have to choose: steady enough to average out the gait's 0.1-0.2 m/s wobble of the leg
midpoint, or quick enough to follow a sidestep. The measurement noise comes with each detection (a
leg-pair midpoint jitters with the gait more than a circle fit), larger where the detection's kind
changed (another point of the body). A lone leg of a track seen as a leg pair before is one of a
person's legs: the centre lies anywhere within half the widest pair of it, an offset that the filter holds as
a state while the same leg stands (each detection of it carries the same offset, not a new error). Two lone
legs standing where the track's legs stood are the person's two legs, measured as the pair they are. A
confirmed track does not take a detection without motion evidence where the static map saw something stand
before (``Detection.held``) outside its body's footprint: that is the background beside it, not its body.

The laser sees only the front surface of a round body, so the centroid of the hit points sits
about half a radius too close (``shared/protocols/psm.md`` §9.14). The body's centre is found by
fitting a circle to the points (algebraic fit, then a fixed-radius refinement with the track's
smoothed radius); when the arc is too short for a fit, the centre is put one radius behind the
nearest point along the viewing ray.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any, ClassVar, Protocol

import numpy as np
from numba import njit

from .person import PersonSize, leg_reach_m
from .types import Pose2D

if TYPE_CHECKING:
    from .person import PersonKeys


class PoseUncertainty(Protocol):
    """The relative error of two matched laser poses (implemented by :class:`vipsm.seen_through.ScanMemory`)."""

    config: Any  # with ``sigma_gate``

    def relative_heading_sigma_rad(self, a: Pose2D, sigma_a_rad: float, b: Pose2D, sigma_b_rad: float) -> float: ...

    def relative_position_sigma_m(self, a: Pose2D, b: Pose2D) -> float: ...


#: a detection's position noise when it carries none of its own (``Detection.sigma_m`` None: the estimator
#: gives every detection its kind's noise, so this only serves detections built without one): a circle fit's
#: 2-3 cm
DEFAULT_SIGMA_M = 0.03

#: the circle fit of a body (``locate_body``). Constants of the fit, not of a world: a body's radius before any
#: fit gave one (between a person's 0.25 m and a cart's half width) ...
DEFAULT_RADIUS_M = 0.30
#: ... the radii a fit may give (a thin post's 5 cm to a 3 m wide thing: wider is a wall, not a body) ...
MIN_FIT_RADIUS_M, MAX_FIT_RADIUS_M = 0.05, 1.50
#: ... the arc (seen from the fitted centre) the points must span to define a circle rather than a line ...
MIN_FIT_EXTENT_RAD = math.radians(25.0)
#: ... and the weight of a new fit in a track's radius: a rigid body's radius is a constant, so its estimate is
#: the mean of its fits, over about the last 1 / this of them (the first fit alone, often a partial view, does
#: not hold it)
RADIUS_SMOOTHING = 0.2

#: a circle fit whose radius differs from the track's by more than this share is no displacement evidence (a
#: rigid round body keeps its radius; a box corner's fit changes with the visible part) ...
RADIUS_TOL = 0.3
#: ... and within this share for a partly occluded fit (a round body's partial fit keeps its radius)
OCCLUDED_RADIUS_TOL = 0.1

#: confirmation's shape of a path (shares, not sizes: they hold at any speed and scale). A path needs three
#: detections (two steps define a direction and whether it holds), two of them with motion evidence (one can
#: be a flow error or a stray return) ...
CONFIRM_HITS, CONFIRM_EVIDENCE = 3, 2
#: ... a nearly straight path (net / travelled: jumping between a chair's legs is not) ...
CONFIRM_STRAIGHTNESS = 0.6
#: ... made step by step: this share of the steps advance along the net displacement (a static thing's
#: detection sits still and then jumps once, e.g. a box corner's circle fit) ...
CONFIRM_ADVANCING = 0.7
#: ... or, for a body that stood and started to move, two steps in a row from its last standing place (a fit
#: that sits still and jumps once does not advance twice in a row)
ONSET_STEPS = 2
#: how far a detection of another kind may lie from the body's centre: a lone leg's centre lies up to half the
#: widest leg pair (``PeopleConfig.leg_pair_max_m``, 0.65 m) from the pair's midpoint. A constant at its
#: measured 0.33 m rather than derived from that key: the derived 0.325 m let a real recording's background
#: be reported as moving (``eval --data real``; docs/estimator.md stage 6)
KIND_CHANGE_M = 0.33
#: reporting: over the report window (and its newer half) the detections go somewhere, net displacement at
#: least this share of the path (a standing person's detections jump back and forth by 0.1-0.3 m)
REPORT_STRAIGHTNESS = 0.35


@dataclass(frozen=True)
class TrackerConfig:
    """The tracker's keys (issue 29: 38 before, 20 now), each a speed, distance, duration or count of a body,
    the sensor or the computer; the fit's and the path tests' constants above are the model's, not a world's."""

    #: process noise of each constant-velocity model of the IMM: steady walking, manoeuvring (m/s^2)
    accel_sigmas_mps2: tuple[float, ...] = (0.2, 2.0)
    #: rate of switching from one model to another (0.05 per 0.1 s; a manoeuvre every 2 s or so)
    mode_switch_per_s: float = 0.5129
    #: a detection's smaller noise across the direction of motion (``Detection.sigma_across_m``)
    #: applies from this speed on (below it the direction is not known well, and a standing person's
    #: midpoint shuffles every way)
    anisotropic_min_speed_mps: float = 0.3
    #: a new track's speed uncertainty (1 sigma): a body first seen may walk any way at a walker's speed
    init_speed_sigma_mps: float = 1.0
    #: association gate around the predicted position: a walker covers at most ~0.2 m per 0.1 s cycle
    gate_m: float = 0.35
    max_missed_s: float = 1.0  # a track unseen longer than this is dropped
    #: ... an unconfirmed one (its covariance, and so its gate, grows fast: coasting longer it would take
    #: a detection a metre away as its own)
    tentative_max_missed_s: float = 0.3
    #: an unconfirmed track this old is dropped: in 1 s the slowest body of interest (0.15 m/s) moves
    #: 0.15 m, far more than confirmation needs; what has not moved is static, and left alive it would
    #: grab a neighbour's detection one day and "move"
    tentative_max_age_s: float = 1.0
    report_missed_s: float = 0.2  # tracks unseen for at most this long are still reported
    #: over the last ``confirm_window`` detections (a path needs so many points, however often they come)
    #: the body moved at least this far (a lone leg: ``step_noise_m``, what a static leg's placed centre
    #: drifts by) ...
    confirm_displacement_m: float = 0.06
    confirm_window: int = 6
    #: ... from a place the body left: no other detection came within this much of the window's first
    #: position after it (a leg's width plus its centre's jitter). A track that hopped between two
    #: table legs 0.7 m apart (one cycle paired as a person) "moved" while both stood where they were; a
    #: walker's old place is empty, a stance foot there is part of it
    confirm_vacated_m: float = 0.15
    #: the least advance that is motion, above a circle-fitted centre's 2-3 cm of noise and below a walker's 5 cm
    #: a cycle (0.5 m/s): each step of a body that stood and started to move (``ONSET_STEPS`` of them in a row),
    #: and the net displacement of a circle-fitted body with motion evidence in every detection of a window of
    #: at least 4
    confirm_onset_step_m: float = 0.03
    #: detections of one body never jump faster than this plus ``step_noise_m`` between cycles (a flip
    #: of the association between two nearby things, e.g. a chair's legs, does)
    max_speed_mps: float = 2.5
    #: how far a static body's placed centre drifts between its detections: the noisiest kind, a lone leg
    #: placed from 4-5 returns a leg's radius behind them, drifts up to 7 cm in half a second as the robot
    #: drives past (a table leg); also the displacement lone legs must show to confirm (a walker covers
    #: 10 cm in 0.1-0.3 s)
    step_noise_m: float = 0.1
    #: confirmed tracks slower than this (a body that stopped) are not reported: both the filter's
    #: speed and the net displacement of the detections over the last ``report_window`` of them
    report_min_speed_mps: float = 0.08
    #: (detections; its newer half, ``report_recent``, is judged too: a walker who stopped half a window ago)
    report_window: int = 10
    #: ... and the least-squares velocity of the detections over the window must reach this speed (a
    #: standing person's detections jump by ~0.1-0.2 m between one leg and two, which a line fit
    #: averages out; the slowest body of interest moves at 0.15 m/s)
    report_window_speed_mps: float = 0.12
    #: the most tracks alive at once (bounds the cost per cycle however cluttered the room)
    max_tracks: int = 24
    #: a track born from motion evidence starts at its body's detections of up to this long before that
    #: no confirmed track holds (chained back nearest first within a walker's step): a slow
    #: body is seen before its motion is (the camera's flow needs frames 0.3 s apart, the free-space grid
    #: a cell's width of motion), and that stretch already shows whether it moves. They are remembered,
    #: not judged: confirmation comes at the earliest with the next cycle's detection.
    retro_s: float = 0.5

    #: keys removed (issue 29: fewer tuned parameters), with what replaced each: a config file that sets one
    #: is refused naming the key and this reason (``app.config``), never silently misread
    REMOVED_KEYS: ClassVar[dict[str, str]] = {
        "confirm_displacement_leg_m": "the same drift of a placed centre as step_noise_m, which now sets it",
        "kind_change_m": "now a constant, 0.33 m (vipsm.tracker.KIND_CHANGE_M): a lone leg's centre lies up to "
                         "half the widest leg pair from the pair's midpoint",
        "merge_m": "derived: people.person_radius_m (a younger track within a person's radius of an older one is "
                   "the same body)",
        "confirm_displacement_sustained_m": "merged into confirm_onset_step_m: the same least advance that is "
                                            "motion (3 cm, above a circle fit's noise)",
        "report_recent": "derived: report_window // 2 (the window's newer half)",
        "meas_sigma_m": "now a constant, 0.03 m, for a detection without its own noise "
                        "(vipsm.tracker.DEFAULT_SIGMA_M): the estimator gives every detection its kind's",
        "default_radius_m": "now a constant of the circle fit, 0.30 m (vipsm.tracker.DEFAULT_RADIUS_M)",
        "min_radius_m": "now a constant of the circle fit, 0.05 m (vipsm.tracker.MIN_FIT_RADIUS_M)",
        "max_radius_m": "now a constant of the circle fit, 1.5 m (vipsm.tracker.MAX_FIT_RADIUS_M)",
        "min_fit_extent_rad": "now a constant of the circle fit, 25 deg (vipsm.tracker.MIN_FIT_EXTENT_RAD)",
        "radius_smoothing": "now a constant of the circle fit, 0.2 (vipsm.tracker.RADIUS_SMOOTHING)",
        "confirm_radius_tol": "now a constant share, 0.3 (vipsm.tracker.RADIUS_TOL)",
        "confirm_occluded_radius_tol": "now a constant share, 0.1 (vipsm.tracker.OCCLUDED_RADIUS_TOL)",
        "confirm_hits": "now a constant, 3: two steps define a direction (vipsm.tracker.CONFIRM_HITS)",
        "confirm_evidence": "now a constant, 2: one can be a flow error (vipsm.tracker.CONFIRM_EVIDENCE)",
        "confirm_onset_rows": "now a constant, 2 steps in a row (vipsm.tracker.ONSET_STEPS)",
        "confirm_straightness": "now a constant share, 0.6 (vipsm.tracker.CONFIRM_STRAIGHTNESS)",
        "confirm_advancing": "now a constant share, 0.7 (vipsm.tracker.CONFIRM_ADVANCING)",
        "report_straightness": "now a constant share, 0.35 (vipsm.tracker.REPORT_STRAIGHTNESS)",
    }

    def __post_init__(self) -> None:
        if not self.accel_sigmas_mps2 or min(self.accel_sigmas_mps2) <= 0.0:
            raise ValueError(f"accel_sigmas_mps2 needs at least one positive value, got {self.accel_sigmas_mps2}")
        if self.mode_switch_per_s < 0.0:
            raise ValueError(f"mode_switch_per_s must be >= 0, got {self.mode_switch_per_s}")
        if self.report_window < 4 or self.confirm_window < 3:
            raise ValueError("need report_window >= 4 (its newer half needs 2) and confirm_window >= 3")
        if min(self.max_missed_s, self.tentative_max_missed_s, self.tentative_max_age_s, self.report_missed_s) < 0.0:
            raise ValueError("the tracker's durations must be >= 0")
        if self.max_tracks < 1 or self.retro_s < 0.0 or self.confirm_vacated_m < 0.0:
            raise ValueError("need max_tracks >= 1, retro_s >= 0 and confirm_vacated_m >= 0")
        if not self.confirm_onset_step_m > 0.0:
            raise ValueError(f"need confirm_onset_step_m > 0, got {self.confirm_onset_step_m}")
        if not self.anisotropic_min_speed_mps > 0.0:  # a standing track has no direction of motion
            raise ValueError(f"need anisotropic_min_speed_mps > 0, got {self.anisotropic_min_speed_mps}")

    @property
    def report_recent(self) -> int:
        """The report window's newer half (detections): a walker who stopped half a window ago still shows
        the walk in the window's older half."""
        return self.report_window // 2


@dataclass(frozen=True)
class Detection:
    x_m: float
    y_m: float
    radius_m: float
    radius_fitted: bool
    scan_index_start: int
    scan_index_stop: int
    bearing_min_rad: float
    bearing_max_rad: float
    #: whether this detection shows motion (free-space violation or camera)
    evidence: bool = True
    #: position noise of this detection (None: ``DEFAULT_SIGMA_M``)
    sigma_m: float | None = None
    #: ... across the track's direction of motion, when smaller than along it (None: the same): a
    #: walker's leg-pair midpoint moves stop-and-go along the path with the alternating steps, but
    #: sideways only with the body's small sway
    sigma_across_m: float | None = None
    kind: str = "body"
    #: partly hidden by something nearer: a centre placed an assumed radius behind the visible points
    #: follows the occluder's edge and does not count as displacement for confirmation; a circle fitted
    #: to a round body's visible part keeps the body's radius, one fitted to a box's does not (a box
    #: uncovered by a passing body: its fit moved 11 cm as the radius went 0.33 -> 0.24 m), so it counts
    #: only with its radius within ``OCCLUDED_RADIUS_TOL``
    occluded: bool = False
    #: a fitted circle's: the world-frame direction from its visible surface (the returns' middle) to its centre
    #: (``vipsm.bodies.Body.behind_rad``; NaN: unknown). The centre lies its radius behind the surface along this
    #: line, so a change of the fitted radius moves the centre along it with nothing moving: confirmation and
    #: reporting take that out (a box 4.3 m away whose fit grew 0.19 -> 0.26 m as more of a face showed "moved"
    #: 5.5 cm away from the robot, its front 1.3 cm). For a round body seen whole it is the view line from the
    #: laser; for a flat face seen obliquely, the face's normal: an open door's leaf 27-28 deg off the view line,
    #: fitted 1.28 -> 1.49 m as the curl of its ends changed, slid 0.21 m along its normal, and taken out along
    #: the view line that left 0.1 m of "motion" across it, reported (tests/vipsm/test_tracker_face.py)
    behind_rad: float = math.nan
    #: the world-frame laser pose (x_m, y_m, theta_rad) of the scan the detection came from and that scan's own
    #: heading error (1 sigma; NaN: unknown): two detections placed with two matched poses differ by the
    #: poses' relative error, which confirmation must not read as displacement (see ``Tracker``)
    laser_x_m: float = math.nan
    laser_y_m: float = math.nan
    laser_theta_rad: float = math.nan
    heading_sigma_rad: float = math.nan
    #: something stood where its returns lie when the laser last saw that place (before this scan; tracked moving
    #: bodies write no occupancy): the static background, unless it shows motion (``evidence``)
    held: bool = False
    #: a leg pair's or a lone leg's: the centres of its legs (world frame), one per leg seen
    legs_xy: tuple[tuple[float, float], ...] = ()


def fit_circle(points: np.ndarray) -> tuple[float, float, float] | None:
    """Algebraic (Kasa) circle fit: (cx, cy, r) or None if degenerate."""
    if points.shape[0] < 3:
        return None
    x, y = points[:, 0], points[:, 1]
    mx, my = x.mean(), y.mean()
    u, v = x - mx, y - my
    a = np.stack([u, v, np.ones_like(u)], axis=1)
    rhs = -(u * u + v * v)
    sol, _, rank, _ = np.linalg.lstsq(a, rhs, rcond=None)
    if rank < 3:
        return None
    cx, cy = -sol[0] / 2.0, -sol[1] / 2.0
    r2 = cx * cx + cy * cy - sol[2]
    if not r2 > 0:
        return None
    return float(cx + mx), float(cy + my), float(math.sqrt(r2))


def refine_fixed_radius(
    points: np.ndarray, cx: float, cy: float, radius: float, iterations: int = 6
) -> tuple[float, float]:
    """Gauss-Newton on sum (|p - c| - R)^2 with R fixed (compiled: it runs for every leg-sized
    segment of every scan)."""
    pts = np.ascontiguousarray(points, dtype=np.float64)
    return _gauss_newton_fixed_radius(pts[:, 0], pts[:, 1], float(cx), float(cy), float(radius), int(iterations))


@njit(cache=True, nogil=True, error_model="numpy")
def _gauss_newton_fixed_radius(px, py, cx, cy, radius, iterations):  # pragma: no cover - compiled
    for _ in range(iterations):
        a11 = a12 = a22 = g1 = g2 = 0.0
        for k in range(px.size):
            dx, dy = px[k] - cx, py[k] - cy
            rho = max(math.hypot(dx, dy), 1e-9)
            jx, jy = -dx / rho, -dy / rho  # d(rho - R)/d(cx, cy)
            res = rho - radius
            a11 += jx * jx
            a12 += jx * jy
            a22 += jy * jy
            g1 -= jx * res
            g2 -= jy * res
        det = a11 * a22 - a12 * a12
        if abs(det) < 1e-12:
            break
        sx, sy = (a22 * g1 - a12 * g2) / det, (a11 * g2 - a12 * g1) / det
        cx += sx
        cy += sy
        if math.hypot(sx, sy) < 1e-5:
            break
    return cx, cy


def locate_body(
    points: np.ndarray, sensor_xy: tuple[float, float], radius_hint_m: float | None
) -> tuple[float, float, float, bool]:
    """Centre (x, y), radius and whether the radius came from a fit, for a round body whose front
    surface produced ``points`` (k x 2, world frame), seen from ``sensor_xy``."""
    centroid, ray_n = _viewing_ray(points, sensor_xy)
    fit = fit_circle(points) if points.shape[0] >= 5 else None
    fitted = False
    radius = radius_hint_m if radius_hint_m is not None else DEFAULT_RADIUS_M
    if fit is not None:
        fx, fy, fr = fit
        # the centre must lie behind the points as seen from the sensor
        behind = (fx - centroid[0]) * ray_n[0] + (fy - centroid[1]) * ray_n[1] > 0.0
        ang = np.arctan2(points[:, 1] - fy, points[:, 0] - fx)
        extent = float(np.ptp(np.unwrap(ang))) if ang.size > 1 else 0.0
        if behind and MIN_FIT_RADIUS_M <= fr <= MAX_FIT_RADIUS_M and extent >= MIN_FIT_EXTENT_RAD:
            fitted = True
            if radius_hint_m is None:
                radius = fr
    cx, cy = _centre_behind(points, sensor_xy, radius, ray_n)
    return cx, cy, radius, fitted


def locate_round(points: np.ndarray, sensor_xy: tuple[float, float], radius_m: float) -> tuple[float, float]:
    """Centre (x, y) of a round body of a known radius (a leg) whose front surface produced ``points``:
    :func:`locate_body`'s centre with that radius as the hint, without the circle fit it does not use."""
    return _centre_behind(points, sensor_xy, radius_m, _viewing_ray(points, sensor_xy)[1])


def _viewing_ray(points: np.ndarray, sensor_xy: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
    """The points' centroid and the unit vector from the sensor towards it."""
    centroid = points.mean(axis=0)
    ray = centroid - np.array(sensor_xy)
    return centroid, ray / max(float(np.hypot(ray[0], ray[1])), 1e-9)


def _centre_behind(points: np.ndarray, sensor_xy: tuple[float, float], radius: float, ray_n: np.ndarray
                   ) -> tuple[float, float]:
    """The nearest point pushed back by the radius along the viewing ray, then refined."""
    d = points - np.array(sensor_xy)
    near = points[int(np.argmin(np.hypot(d[:, 0], d[:, 1])))]
    start = near + radius * ray_n
    if points.shape[0] >= 3:
        cx, cy = refine_fixed_radius(points, float(start[0]), float(start[1]), radius)
        # keep the refinement only if it stayed behind the surface and near the start
        if math.hypot(cx - start[0], cy - start[1]) > 2.0 * radius + 0.2:
            cx, cy = float(start[0]), float(start[1])
    else:
        cx, cy = float(start[0]), float(start[1])
    return cx, cy


def _combine(track: Track) -> None:
    """The track's state and covariance from its models' (a mixture's mean and spread); the leg offset
    (``Track.model_states``' last two) stays inside the models."""
    mu, xs = track.model_probs, track.model_states
    full = mu @ xs
    d = xs - full
    cov = np.einsum("i,ikl->kl", mu, track.model_covs + d[:, :, None] * d[:, None, :])
    track.state, track.cov = full[:4].copy(), cov[:4, :4].copy()


def _fresh_offset(states: np.ndarray, covs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The models' states and covariances with the leg offset forgotten: another leg's, anywhere within a
    person's reach (``KIND_CHANGE_M``) of the centre and independent of the rest."""
    xs, ps = states.copy(), covs.copy()
    xs[:, 4:] = 0.0
    ps[:, 4:, :] = 0.0
    ps[:, :, 4:] = 0.0
    ps[:, 4, 4] = ps[:, 5, 5] = KIND_CHANGE_M**2
    return xs, ps


#: a fitted circle seen over less than this arc of it is a flat face's: its centre was inferred from a curvature
#: (a door leaf's 0.9 m face, the curl of its ends 2-3 cm, fitted 1.3-1.45 m: 24-34 deg), not seen as a round
#: body's half circle or a box corner's two faces
FACE_ARC_MAX_RAD = math.pi / 2.0


def _turns_as_a_face(det: Detection) -> bool:
    """A fitted detection, seen whole, whose returns span less than ``FACE_ARC_MAX_RAD`` of its circle (the span's
    chord from its bearings and the laser's distance to its surface): a flat face, whose fitted centre swings with
    the face's turn (:func:`_fit_invariant`). Unknown laser position: not judged."""
    if not det.radius_fitted or det.occluded or not (math.isfinite(det.laser_x_m) and math.isfinite(det.behind_rad)):
        return False
    sx, sy = _surface_xy(det)
    chord = 2.0 * math.hypot(sx - det.laser_x_m, sy - det.laser_y_m) * math.tan(
        0.5 * abs(det.bearing_max_rad - det.bearing_min_rad))
    return 2.0 * math.asin(min(1.0, 0.5 * chord / det.radius_m)) < FACE_ARC_MAX_RAD


def _surface_xy(det: Detection) -> tuple[float, float]:
    """A fitted detection's visible surface (the returns' middle): its fitted radius in front of its centre."""
    return (det.x_m - det.radius_m * math.cos(det.behind_rad), det.y_m - det.radius_m * math.sin(det.behind_rad))


def _centre_behind_surface(det: Detection, radius_m: float) -> np.ndarray:
    """A rigid body's centre from a fitted detection: the track's radius ``radius_m`` behind the visible surface
    (the returns' middle). The tracker holds every body as a round one of one radius; a fit of another radius
    tells where the surface is, not the centre (a box's fit grows and shrinks as a corner turns into view). Behind
    it along the line the fit puts its centre on (``Detection.behind_rad``: the view line for a round body seen
    whole), or, for a flat face (:func:`_turns_as_a_face`), whose fitted centre lies behind it along its normal
    and swings with the face's turn, along the view line from the laser."""
    ux, uy = math.cos(det.behind_rad), math.sin(det.behind_rad)
    sx, sy = _surface_xy(det)
    if _turns_as_a_face(det):
        vx, vy = sx - det.laser_x_m, sy - det.laser_y_m
        d = max(math.hypot(vx, vy), 1e-6)
        ux, uy = vx / d, vy / d
    return np.array([sx + radius_m * ux, sy + radius_m * uy])


#: a track's filter state per model: x, y, vx, vy and the offset of the person's lone leg seen last from its
#: centre (``Tracker._update``)
_N_STATE = 6
#: the measurement of a person's lone leg: its centre plus the leg's offset
_H_LEG = np.hstack([np.eye(2), np.zeros((2, 2)), np.eye(2)])


#: durations are compared with differences of scan stamps, which carry rounding: this much is equal
_STAMP_TOL_S = 1e-3


#: detection kinds as numbers in a track's history
_KIND_CODE = {"body": 0.0, "leg": 1.0, "person": 2.0}


def kind_aligned(rows: np.ndarray) -> tuple[np.ndarray, tuple[float, float]]:
    """(stamp_s, x_m, y_m, kind) rows of one body: the least-squares velocity common to all rows with
    an offset per kind (a lone leg's centre and a leg pair's midpoint are different points of a person,
    so a change of kind moves the detection without the body moving), and the positions moved onto the
    newest row's kind by those offsets. A kind seen once carries no velocity information."""
    t, xy, kinds = rows[:, 0], rows[:, 1:3].copy(), rows[:, 3]
    v, _ = _kind_fit(t, xy, kinds, np.ones(t.size))
    offsets = {k: xy[kinds == k].mean(axis=0) - v * t[kinds == k].mean() for k in np.unique(kinds)}
    aligned = xy - np.array([offsets[k] for k in kinds]) + offsets[kinds[-1]]
    return aligned, (float(v[0]), float(v[1]))


def _kind_fit(t: np.ndarray, xy: np.ndarray, kinds: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, float]:
    """The weighted (``w``) least-squares velocity common to rows at stamps ``t`` and positions ``xy`` with an
    offset per kind (``kinds``), and its information (weight times squared time spread: one over the speed's
    variance for weights one over each row's variance); zero velocity and information without a spread."""
    tc, xyc = np.empty_like(t), np.empty_like(xy)
    for k in set(kinds.tolist()):  # per kind: its weighted means (as np.average computes them, without its checks)
        m = kinds == k
        wm = w[m]
        sw = wm.sum()
        tc[m] = t[m] - np.multiply(t[m], wm).sum() / sw
        xyc[m] = xy[m] - np.multiply(xy[m], wm[:, None]).sum(axis=0) / sw
    info = float(w @ tc**2)
    return ((w * tc) @ xyc / info if info > 0.0 else np.zeros(2)), info


def _kind_slack_m(a: Detection, b: Detection, kind_change_m: float) -> float:
    """How far apart two detections of one body may be placed with the body still: 0 for one kind; a lone leg
    and a leg pair's midpoint up to ``kind_change_m`` (half the widest pair); a round body (the legs seen as
    one segment) and a leg or a pair inside its outline: up to its fitted radius. A wall piece's circle fit
    and a thin post 0.7 m beside it are not one body (a track chaining from one to the other "moves" 0.7 m
    with nothing moving)."""
    if a.kind == b.kind:
        return 0.0
    if "body" in (a.kind, b.kind):
        return max(d.radius_m for d in (a, b) if d.kind == "body")
    return kind_change_m


def _pair_of(a: Detection, b: Detection, default_sigma_m: float) -> Detection:
    """Two lone legs of one person measured as a leg pair: their midpoint, with the noise of a mean of two."""
    sigma = 0.5 * math.hypot(*(default_sigma_m if d.sigma_m is None else d.sigma_m for d in (a, b)))
    mx, my = 0.5 * (a.x_m + b.x_m), 0.5 * (a.y_m + b.y_m)
    return replace(a, x_m=mx, y_m=my, kind="person", sigma_m=sigma, sigma_across_m=None,
                   evidence=a.evidence or b.evidence, occluded=a.occluded or b.occluded,
                   scan_index_start=min(a.scan_index_start, b.scan_index_start),
                   scan_index_stop=max(a.scan_index_stop, b.scan_index_stop),
                   bearing_min_rad=min(a.bearing_min_rad, b.bearing_min_rad),
                   bearing_max_rad=max(a.bearing_max_rad, b.bearing_max_rad), behind_rad=math.nan,
                   legs_xy=a.legs_xy + b.legs_xy)


def _onset(hist: np.ndarray) -> int:
    """Index of the first of the history rows' trailing run with motion evidence (len: none)."""
    still = np.flatnonzero(hist[:, 3] == 0.0)
    return int(still[-1]) + 1 if still.size else 0


def _fit_invariant_xy(hist: np.ndarray) -> np.ndarray:
    """A track's history rows' positions with each fitted centre moved along the line it lies behind its
    visible surface on (``Detection.behind_rad``) by its radius's difference from the newest fit's: what the
    visible surface did (a box's fit grows and recedes as a face turns into view, a flat face's with the curl of
    its ends; a round body's keeps its radius, and so its centre)."""
    if not np.isfinite(hist[-1, 7]):
        return hist[:, 1:3].copy()
    return _fit_invariant(hist[:, 1:3], hist[:, 7], hist[:, 8])


def _fit_invariant(xy: np.ndarray, radius: np.ndarray, behind: np.ndarray,
                   laser_xy: np.ndarray | None = None, face: np.ndarray | None = None) -> np.ndarray:
    """Positions ``xy`` (k x 2) of fitted centres (``radius`` NaN: not a fit) moved along the lines they lie
    behind their visible surfaces on (``behind``, world-frame directions from the surface to the centre) by
    their radius's difference from the newest fit's. With ``laser_xy`` (k x 2, where each was seen from) the
    flat faces' fits (``face`` 1.0, :func:`_turns_as_a_face`) are also turned onto the newest fit's direction
    against the view line: put the newest radius behind their surfaces along the direction that lies as far from
    the view line to that surface as the newest fit's does from its own (another body's fit, a round body's, a
    box corner's or a partly hidden one, whose direction turns with the part seen, keeps its own; all do where
    the newest is not a face's). A flat face's fitted centre lies its radius (1.3-1.45 m for a door leaf) behind
    the face along its normal and swings with the face's turn, three times as far as the face moves and across
    its motion; a round body seen whole lies behind its surface along the view line and keeps its centre."""
    xy = xy.copy()
    ok = np.isfinite(radius) & np.isfinite(behind)
    if not ok.any():
        return xy
    r, b = radius[ok], behind[ok]
    surface = xy[ok] - r[:, None] * np.stack([np.cos(b), np.sin(b)], axis=1)
    direction = b.copy()
    if laser_xy is not None:
        lx = laser_xy[ok]
        seen = np.all(np.isfinite(lx), axis=1)
        if face is not None:
            seen &= face[ok] == 1.0
        if seen[-1]:
            view = np.arctan2(surface[:, 1] - lx[:, 1], surface[:, 0] - lx[:, 0])
            direction[seen] = view[seen] + (b[-1] - view[-1])
    xy[ok] = surface + r[-1] * np.stack([np.cos(direction), np.sin(direction)], axis=1)
    return xy


def _report_rows(recent: list[tuple[float, ...]], turned: bool = False) -> np.ndarray:
    """A track's report window as (stamp_s, x_m, y_m, kind) rows, each fitted centre moved as in
    :func:`_fit_invariant`: a standing box whose visible part shrinks as the robot comes closer (its fit
    0.36 -> 0.12 m) moves its fitted centre 0.24 m with nothing moving, and a track that stopped was
    reported again on it. Reporting takes both views: a moving box's fit changes as well. ``turned``: each
    flat face's fit also turned onto the newest fit's direction against the view line (for :func:`_fit_moved_less`
    only, the young window's judgement)."""
    rows = np.array(recent)
    out = rows[:, :4].copy()
    if turned and rows.shape[1] >= 11:
        out[:, 1:3] = _fit_invariant(rows[:, 1:3], rows[:, 4], rows[:, 5], rows[:, 8:10], rows[:, 10])
    elif rows.shape[1] >= 6:
        out[:, 1:3] = _fit_invariant(rows[:, 1:3], rows[:, 4], rows[:, 5])
    return out


def _fit_moved_less(raw: np.ndarray, fit_invariant: np.ndarray) -> bool:
    """A young report window (stamp_s, x_m, y_m, kind rows, as placed and as :func:`_report_rows` with ``turned``)
    whose body moved at least as far as its fits' change moved their centres: from its first detection to its
    newest, the displacement with each fitted centre moved by its radius's change and turned onto the newest fit's
    direction against the view line is no shorter than what that change accounts for. A flat face whose fit grows
    as the laser passes slides its centre along its normal with the face standing; a door leaf in the last of its
    swing, turning against the view line, swings its fitted centre 1.3 m behind it three times as far as the face
    moves; a body with no fit, or a round one that keeps its radius and faces the laser, moves as placed."""
    moved = fit_invariant[-1, 1:3] - fit_invariant[0, 1:3]
    by_radius = (raw[-1, 1:3] - raw[0, 1:3]) - moved
    return bool(np.hypot(*moved) >= np.hypot(*by_radius))


@dataclass
class Track:
    track_id: int
    state: np.ndarray  # x, y, vx, vy
    cov: np.ndarray  # 4x4
    radius_m: float
    stamp_s: float
    hits: int = 1
    missed: int = 0  # cycles since its last detection
    age_cycles: int = 1
    #: stamps of its first (chained) and its last detection
    born_s: float = 0.0
    seen_s: float = 0.0
    #: the last detections: (stamp_s, x_m, y_m, 1.0 if it showed motion evidence else 0.0, kind code,
    #: 1.0 if its position is unreliable for displacement else 0.0: see ``Tracker._remember``, the
    #: radius of a circle fitted to a partly occluded view, else NaN; the fitted radius, else NaN; the
    #: direction ``Detection.behind_rad``; the laser pose x, y, theta and its heading sigma)
    history: list[tuple[float, ...]] = field(default_factory=list)
    evidence: int = 0
    confirmed: bool = False
    #: the last ``report_window`` detections: (stamp_s, x_m, y_m, kind code, fitted radius or NaN, behind_rad,
    #: 1.0 if the confirmed track's filter stood with it (``Tracker._stands``) else 0.0, its noise about the
    #: point of the body its kind sees, ``Tracker._point_noise_m``;
    #: the laser position x, y it was seen from; 1.0 if a flat face's fit, ``_turns_as_a_face``, else 0.0)
    recent: list[tuple[float, ...]] = field(default_factory=list)
    kind: str = "body"
    #: a detection of it was a leg pair: a lone leg is then one of its legs, not its centre
    seen_as_person: bool = False
    #: the IMM's models: state (n, 6: x, y, vx, vy and the offset of the person's lone leg seen last from the
    #: centre, ``Tracker._update``), covariance (n, 6, 6) and probability (n) of each; ``state`` and ``cov`` are
    #: their combination's first four
    model_states: np.ndarray = field(default_factory=lambda: np.zeros((0, _N_STATE)))
    model_covs: np.ndarray = field(default_factory=lambda: np.zeros((0, _N_STATE, _N_STATE)))
    model_probs: np.ndarray = field(default_factory=lambda: np.zeros(0))
    #: the confirmed track's filter holds it still (``Tracker._stands``)
    standing: bool = False
    #: how many fitted radii it has had (``radius_m`` is their mean, ``Tracker._update``)
    fits: int = 0
    #: the leg centres of its last detection (``Detection.legs_xy``)
    legs_xy: tuple[tuple[float, float], ...] = ()

    @property
    def radius_known(self) -> bool:
        return self.fits > 0

    @property
    def speed_mps(self) -> float:
        return math.hypot(float(self.state[2]), float(self.state[3]))


class Tracker:
    """Constant-velocity Kalman filters, greedy nearest-neighbour association with a gate."""

    def __init__(self, config: TrackerConfig | None = None, poses: PoseUncertainty | None = None,
                 person: PersonKeys | None = None) -> None:
        """``poses``: the relative error of two matched laser poses (:class:`vipsm.seen_through.ScanMemory`);
        None: detections are taken as placed without pose error. ``person``: a person's size, the people
        stage's keys (``PeopleConfig``; None: their defaults, :class:`vipsm.person.PersonSize`)."""
        self.config = config or TrackerConfig()
        person = person or PersonSize()
        #: a younger track within a person's radius of an older one is the same body (``merge_m``, 0.25 m)
        self.merge_m = person.person_radius_m
        self._person = person
        self._poses = poses
        self.tracks: list[Track] = []
        self._next_id = 1
        #: the detections of the cycles of the last ``retro_s`` that no confirmed track took and that started
        #: no track: (stamp_s, [(detection, id of the unconfirmed track that took it or None)])
        self._past: deque[tuple[float, list[tuple[Detection, int | None]]]] = deque()
        #: :meth:`reported` per track id since the last :meth:`step` (only ``step`` changes a track; the estimator
        #: asks twice a cycle, and the 40 Hz loop at every scan in between)
        self._reported: dict[int, bool] = {}

    @staticmethod
    def unseen_s(track: Track) -> float:
        """How long the track has gone without a detection (at its last prediction's stamp)."""
        return track.stamp_s - track.seen_s

    def recently_seen(self, track: Track) -> bool:
        """Unseen for at most ``report_missed_s``: a coasting track still reported."""
        return self.unseen_s(track) <= self.config.report_missed_s + _STAMP_TOL_S

    def predict_position(self, track: Track, stamp_s: float) -> tuple[float, float]:
        dt = max(stamp_s - track.stamp_s, 0.0)
        return float(track.state[0] + track.state[2] * dt), float(track.state[1] + track.state[3] * dt)

    def _predict(self, track: Track, stamp_s: float) -> None:
        """The IMM's prediction: mix the models' estimates by the switching probabilities, predict each
        with its own process noise, combine."""
        dt = stamp_s - track.stamp_s
        if dt <= 0.0:
            return
        xs, ps, mu = track.model_states, track.model_covs, track.model_probs
        n = mu.shape[0]
        sw = 1.0 - math.exp(-self.config.mode_switch_per_s * dt) if n > 1 else 0.0
        trans = np.full((n, n), sw / max(n - 1, 1))
        np.fill_diagonal(trans, 1.0 - sw)
        prior = trans.T @ mu
        w = trans * mu[:, None] / np.maximum(prior[None, :], 1e-300)  # w[i, j]: from model i into j
        f = np.eye(_N_STATE)
        f[0, 2] = f[1, 3] = dt
        q1 = np.array([[dt**3 / 3.0, dt**2 / 2.0], [dt**2 / 2.0, dt]])
        for j, sigma in enumerate(self.config.accel_sigmas_mps2):
            x0 = w[:, j] @ xs
            d = xs - x0
            p0 = np.einsum("i,ikl->kl", w[:, j], ps + d[:, :, None] * d[:, None, :])
            q = np.zeros((_N_STATE, _N_STATE))
            q[np.ix_([0, 2], [0, 2])] = q1 * sigma**2
            q[np.ix_([1, 3], [1, 3])] = q1 * sigma**2
            # the lone leg's offset from the centre: held while the body stands on it, forgotten as the body moves
            # its own reach past it (a Gauss-Markov offset of spread KIND_CHANGE_M and time constant
            # KIND_CHANGE_M / speed: a walker's stance leg falls behind, a swing leg overtakes)
            keep = math.exp(-math.hypot(x0[2], x0[3]) * dt / KIND_CHANGE_M)
            f[4, 4] = f[5, 5] = keep
            q[4, 4] = q[5, 5] = KIND_CHANGE_M**2 * (1.0 - keep**2)
            track.model_states[j] = f @ x0
            track.model_covs[j] = f @ p0 @ f.T + q
        track.model_probs = prior
        _combine(track)
        track.stamp_s = stamp_s

    def _radius_agrees(self, track: Track, det: Detection) -> bool:
        """A fitted radius (if any) within ``RADIUS_TOL`` of the track's (before it is folded in)."""
        if det.occluded and det.radius_fitted:  # a round body's partial fit keeps its radius; a box's does not
            tol = OCCLUDED_RADIUS_TOL * track.radius_m
            return track.radius_known and abs(det.radius_m - track.radius_m) <= tol
        tol = RADIUS_TOL * track.radius_m
        return not (det.radius_fitted and track.radius_known and abs(det.radius_m - track.radius_m) > tol)

    def _update(self, track: Track, det: Detection) -> None:
        """The IMM's update: each model's Kalman update, the mode probabilities by how well each model
        predicted the detection, combine."""
        z = np.array([det.x_m, det.y_m])
        if (det.radius_fitted and not det.occluded and track.radius_known and not track.seen_as_person
                and math.isfinite(det.behind_rad) and math.isfinite(det.laser_x_m)):
            z = _centre_behind_surface(det, track.radius_m)
        r = self._measurement_cov(track, det)
        h = np.eye(2, _N_STATE)
        if self._leg_offset_applies(track, det):
            h = _H_LEG
            if not self._same_leg(track, det):
                # another leg than the one seen last, or a leg after another kind: its offset is not known
                track.model_states, track.model_covs = _fresh_offset(track.model_states, track.model_covs)
        likelihood = np.empty(track.model_probs.shape[0])
        for j in range(likelihood.shape[0]):
            x, p = track.model_states[j], track.model_covs[j]
            s = h @ p @ h.T + r
            s_inv = np.linalg.inv(s)
            nu = z - h @ x
            k = p @ h.T @ s_inv
            track.model_states[j] = x + k @ nu
            pj = p - k @ h @ p
            track.model_covs[j] = 0.5 * (pj + pj.T)
            likelihood[j] = math.exp(-0.5 * float(nu @ s_inv @ nu)) / (2.0 * math.pi * math.sqrt(np.linalg.det(s)))
        mu = track.model_probs * likelihood
        total = float(mu.sum())
        if total > 0.0 and math.isfinite(total):  # else (a detection no model expects) keep the prior
            track.model_probs = mu / total
        _combine(track)
        if det.radius_fitted:
            track.fits += 1
            a = max(1.0 / track.fits, RADIUS_SMOOTHING)
            track.radius_m = (1.0 - a) * track.radius_m + a * det.radius_m

    @staticmethod
    def _leg_offset_applies(track: Track, det: Detection) -> bool:
        """A person's lone leg: measured as the centre plus the leg's offset, a state of the filter, not a white
        error. Consecutive detections of a leg that stands carry the same offset: as white noise their mean
        pulled the centre onto the leg: a person standing still, its far leg hidden, drifted onto its near leg at
        0.2 m/s.
        The offset is forgotten (``_fresh_offset``) at another leg or after another kind (``_same_leg``)."""
        return det.kind == "leg" and track.seen_as_person

    def _same_leg(self, track: Track, det: Detection) -> bool:
        """The lone leg seen last, standing where it stood (to ``step_noise_m``, how far a static leg's placed
        centre drifts between detections): its offset from the centre is the one the filter holds."""
        if not track.history:
            return False
        last = track.history[-1]
        near = math.hypot(det.x_m - last[1], det.y_m - last[2]) <= self.config.step_noise_m
        return last[4] == _KIND_CODE["leg"] and near

    def _measurement_cov(self, track: Track, det: Detection) -> np.ndarray:
        """The detection's position covariance: its own noise (smaller across the track's motion
        where the detection says so and the track moves at least ``anisotropic_min_speed_mps``), plus,
        in every direction, the offset of another point of the body (a lone leg, the pair's midpoint)
        or of a partly hidden one."""
        c = self.config
        sigma = DEFAULT_SIGMA_M if det.sigma_m is None else det.sigma_m
        extra = 0.0
        if self._leg_offset_applies(track, det):
            # a person's lone leg: the centre lies anywhere within KIND_CHANGE_M of it, an offset of the filter's
            # state (``_leg_offset_applies``), not a white error; the leg's own centre is placed as well as a
            # circle's (the detection's noise, a hip's half-width off the centre, is in that offset)
            extra = 0.0
        elif det.kind != track.kind and not (det.kind == "person" and track.seen_as_person):
            # another point of the body than the last detection's (a lone leg vs the pair's midpoint). Not a
            # person's leg pair: it measures the centre, the filter's own point (a lone leg's offset is a state)
            extra = 0.5 * KIND_CHANGE_M
        if det.occluded:  # only part of the body seen: its centre is anywhere within about a radius
            extra = math.hypot(extra, 0.5 * track.radius_m)
        along = math.hypot(sigma, extra) ** 2
        vx, vy = float(track.state[2]), float(track.state[3])
        speed = math.hypot(vx, vy)
        if det.sigma_across_m is None or speed < c.anisotropic_min_speed_mps:
            return np.eye(2) * along
        uu = np.outer((vx / speed, vy / speed), (vx / speed, vy / speed))
        return along * uu + math.hypot(det.sigma_across_m, extra) ** 2 * (np.eye(2) - uu)

    def _steady(self, pts: np.ndarray, kinds: np.ndarray | None = None, person: bool = False) -> bool:
        """(stamp_s, x_m, y_m, ...) rows: no step faster than a walker (``kinds``: per row, the
        detection's kind code; a step between kinds may also move between a leg and a pair's midpoint;
        for a ``person``, a step between two lone legs may move from one leg to the other, each up to
        ``KIND_CHANGE_M`` from the pelvis)."""
        if pts.shape[0] < 2:
            return True
        c = self.config
        step = np.hypot(np.diff(pts[:, 1]), np.diff(pts[:, 2]))
        allowed = c.max_speed_mps * np.diff(pts[:, 0]) + c.step_noise_m
        if kinds is not None:
            allowed = allowed + KIND_CHANGE_M * (np.diff(kinds) != 0.0)
            if person:
                legs = (kinds[1:] == _KIND_CODE["leg"]) & (kinds[:-1] == _KIND_CODE["leg"])
                allowed = allowed + 2.0 * KIND_CHANGE_M * legs
        return bool(np.all(step <= allowed))

    def _remember(self, t: Track, det: Detection, reliable: bool = True) -> None:
        """The detection into the track's bounded windows (the birth detection too: it is where the
        body's displacement starts). Its position is unreliable for displacement when it was placed an
        assumed radius behind a partly occluded segment, fitted with a radius unlike the track's, or a leg
        pair of other legs than the last pair's (``_recomposed``). A leg pair's midpoint with one leg partly
        hidden is not: that leg is placed a leg's radius behind
        its nearest visible point, at most 1.4 leg radii from its centre, so the midpoint is off by at
        most 0.7 leg radius (4 cm), less than the displacement confirmation needs (a walker stepping out
        from behind a box was held until its three partly hidden pairs left the window, 0.4 s)."""
        t.kind = det.kind
        t.seen_as_person |= det.kind == "person"
        t.legs_xy = det.legs_xy
        t.recent.append((t.stamp_s, det.x_m, det.y_m, _KIND_CODE.get(det.kind, -1.0),
                         det.radius_m if det.radius_fitted else math.nan, det.behind_rad, float(self._stands(t)),
                         self._point_noise_m(t, det), det.laser_x_m, det.laser_y_m, float(_turns_as_a_face(det))))
        del t.recent[: -self.config.report_window]
        t.seen_s = t.stamp_s
        t.history.append((t.stamp_s, det.x_m, det.y_m, float(det.evidence), _KIND_CODE.get(det.kind, -1.0),
                          float(not reliable or (det.occluded and not det.radius_fitted and det.kind != "person")),
                          det.radius_m if det.occluded and det.radius_fitted else math.nan,
                          det.radius_m if det.radius_fitted else math.nan, det.behind_rad, det.laser_x_m,
                          det.laser_y_m, det.laser_theta_rad, det.heading_sigma_rad))
        del t.history[: -self.config.confirm_window]

    def _fold(self, t: Track, det: Detection) -> None:
        """A detection into the track (already predicted to its stamp): the filter, the counts, the
        windows (its radius judged against the track's before the update folds it in, a leg pair's legs against
        the last pair's: ``_recomposed``)."""
        reliable = self._radius_agrees(t, det) and not self._recomposed(t, det)
        self._update(t, det)
        t.hits += 1
        t.evidence += int(det.evidence)
        self._remember(t, det, reliable)

    def _recomposed(self, t: Track, det: Detection) -> bool:
        """A leg pair after a leg pair whose two legs cannot be the last one's two: one of them lies beyond a leg's
        reach in the time between (``leg_reach_m``) from where either was, whichever way the two are matched. The
        midpoint then jumps between two different pairs (a piece of furniture paired with another thing as the view
        changes): another point, not a step of the body."""
        if len(det.legs_xy) != 2 or len(t.legs_xy) != 2:
            return False
        reach = leg_reach_m(self._person, t.stamp_s - t.seen_s)
        (a, b), (p, q) = det.legs_xy, t.legs_xy
        straight = max(math.dist(a, p), math.dist(b, q))
        crossed = max(math.dist(a, q), math.dist(b, p))
        return min(straight, crossed) > reach

    def _confirm(self, t: Track, detections: list[Detection], own: Detection) -> None:
        """Confirmed once: enough hits, motion evidence, and consistent displacement of the detections
        (net distance over the recent window, along a nearly straight path, from a place it left;
        ``detections``: this cycle's, ``own`` the one the track took)."""
        c = self.config
        recent = sum(h[3] for h in t.history)
        if t.confirmed or t.hits < CONFIRM_HITS or recent < CONFIRM_EVIDENCE:
            return
        hist = np.array(t.history)
        # a round body's partial views keep their radius: a fit that shrinks or grows over the window
        # follows the occluder's edge over something else (a box face beside a passing body)
        partial = hist[np.isfinite(hist[:, 6]), 6]
        if partial.size > 1 and np.ptp(partial) > OCCLUDED_RADIUS_TOL * t.radius_m:
            return
        # an unreliable position (placed a radius behind a partly hidden segment, or a fit unlike the
        # track's) is no point of the path: judge the path since the last one (a walker stepping out
        # from behind a table is seen whole three cycles later; waiting for the whole window to pass
        # reported it 0.3 s later still)
        unreliable = np.flatnonzero(hist[:, 5])
        if unreliable.size:
            hist = hist[unreliable[-1] + 1 :]
        if hist.shape[0] < 3:
            return
        # a lone leg's centre and a leg pair's midpoint are different points of a body (and a pair's
        # midpoint jumps when the pairing changes): displacement counts between detections of one kind
        hist = hist[hist[:, 4] == hist[-1, 4]]
        if hist.shape[0] < 3:
            return
        xy = _fit_invariant_xy(hist)
        net = float(np.hypot(*(xy[-1] - xy[0])))
        path = float(np.sum(np.hypot(*np.diff(xy, axis=0).T)))
        # the displacement needed by kind: a lone leg's centre drifts with the viewing angle; a
        # circle-fitted body (good to 2-3 cm) with evidence in every detection of the window needs less
        kind = hist[-1, 4]
        if kind == _KIND_CODE["leg"]:
            needed = c.step_noise_m  # the drift of a static leg's placed centre
        elif kind == _KIND_CODE["body"] and recent == len(t.history) and hist.shape[0] >= 4:
            needed = c.confirm_onset_step_m
        else:
            needed = c.confirm_displacement_m
        allowance = self._pose_allowance_m(hist)
        # a centre placed an assumed radius behind the visible part drifts with the view, independently of the
        # two scans' pose error: they add; a fitted circle's centre does not drift with the view
        needed = max(needed, allowance) if np.isfinite(hist[-1, 7]) else math.hypot(needed, allowance)
        steps = np.diff(xy, axis=0)
        advancing = float(np.mean(steps @ (xy[-1] - xy[0]) > 0.0))
        if (net >= needed and net >= CONFIRM_STRAIGHTNESS * path and advancing >= CONFIRM_ADVANCING
                and self._steady(hist) and self._left(t, hist[0, :3], detections, own)):
            t.confirmed = True
            return
        origin = self._started(hist, xy, needed)
        if origin is not None and self._left(t, hist[origin, :3], detections, own):
            t.confirmed = True

    def _pose_allowance_m(self, hist: np.ndarray) -> float:
        """How far the first and the newest of the history rows may lie apart with nothing moving: the two
        scans' relative pose error (``sigma_gate`` sigmas of their relative heading error times the range,
        and of their relative position error). A still laser's scans differ by a match's few centimetres,
        which the fixed displacements already hold; a laser that drove or turned between them carries one
        match error per keyframe step, which at 6 m is 10 cm (a dark post "moved" that far sideways in a
        turn of 13 degrees). Confirmation adds it to a fixed displacement in quadrature where the centre was
        placed an assumed radius behind the visible part (a lone leg, a pair's legs, an unfitted body): that
        drifts with the view by itself, independently of the pose error; a static object 3 m behind the rear
        laser in a 16 degree turn, seen as lone legs whose visible part grew, "moved" 12 cm, beyond either alone
        (10 and 8 cm), not beyond both (13 cm). A fitted circle's centre does not drift with the view (its
        radius is checked): the larger of the two."""
        a, b = hist[0], hist[-1]
        if self._poses is None or hist.shape[1] < 13 or not np.all(np.isfinite(np.r_[a[9:13], b[9:13]])):
            return 0.0
        pa, pb = (Pose2D(float(r[9]), float(r[10]), float(r[11])) for r in (a, b))
        sigma_rad = self._poses.relative_heading_sigma_rad(pa, float(a[12]), pb, float(b[12]))
        sigma_m = self._poses.relative_position_sigma_m(pa, pb)
        range_m = math.hypot(b[1] - b[9], b[2] - b[10])
        return self._poses.config.sigma_gate * math.hypot(range_m * sigma_rad, sigma_m)

    def _started(self, hist: np.ndarray, xy: np.ndarray, needed: float) -> int | None:
        """A body that stood and started to move: the window's newest detections (at least
        ``ONSET_STEPS``) all show motion evidence, the one before them none, and from that last
        standing place every step advances at least ``confirm_onset_step_m`` along the net
        displacement, which reaches ``needed``. The detections it stood at would otherwise count as
        steps that do not advance until they leave the window (a walker coming head-on from standing
        was confirmed 0.2 s after the evidence; a box corner's fit that sits still and jumps once does
        not advance twice in a row). Returns the row of the last standing place, or None."""
        c = self.config
        e = _onset(hist)
        if e < 1 or hist.shape[0] - e < ONSET_STEPS:
            return None
        path = xy[e - 1 :]
        net = path[-1] - path[0]
        dist = float(np.hypot(*net))
        if dist < needed:
            return None
        advance = np.diff(path, axis=0) @ (net / dist)
        return e - 1 if bool(np.all(advance >= c.confirm_onset_step_m)) and self._steady(hist[e - 1 :]) else None

    def _left(self, t: Track, origin: np.ndarray, detections: list[Detection], own: Detection) -> bool:
        """No detection but the track's own stood within ``confirm_vacated_m`` of ``origin`` (stamp_s,
        x_m, y_m) since: in this cycle (``detections`` but ``own``) or a kept earlier one."""
        c = self.config
        since = [d for past_s, dets in self._past if past_s > origin[0] for d, holder in dets
                 if holder != t.track_id]
        return not any(math.hypot(d.x_m - origin[1], d.y_m - origin[2]) <= c.confirm_vacated_m
                       for d in since + detections if d is not own)

    def _stale(self, t: Track) -> bool:
        """An unconfirmed track whose recent detections all lacked motion evidence: a static thing."""
        h = t.history
        return not t.confirmed and len(h) >= self.config.confirm_window and not any(row[3] for row in h)

    def moving(self, tracked: list[tuple[Track, Detection | None]]) -> list[tuple[Track, Detection | None]]:
        """Of ``tracked`` (``step``'s result), the live tracks reported as moving obstacles: confirmed, seen
        lately and :meth:`reported`. Only these stand for a person the people stage sees walk (the estimator):
        a confirmed track not reported (its report window not yet straight, or one that hopped from a cart onto
        its pusher) has not been seen to walk, and would hide that person (docs/estimator.md, stage 6)."""
        alive = {id(t) for t in self.tracks}
        return [(t, d) for t, d in tracked
                if id(t) in alive and t.confirmed and self.recently_seen(t) and self.reported(t)]

    def _stands(self, t: Track) -> bool:
        """Whether the confirmed track's filter, updated with its newest detection, holds it still, with
        hysteresis: it stands from below ``report_min_speed_mps`` (the speed below which a track is not
        reported) until it reaches ``report_window_speed_mps`` (the speed a walk must show): a standing
        person's filter drifting to 0.08-0.09 m/s on a 5 cm jitter of its pairs has not started."""
        c = self.config
        if t.confirmed and t.speed_mps < c.report_min_speed_mps:
            t.standing = True
        elif t.speed_mps >= c.report_window_speed_mps:
            t.standing = False
        return t.standing

    def reported(self, t: Track) -> bool:
        """:meth:`_judged_reported`, judged once per track between two :meth:`step` calls."""
        if t.track_id not in self._reported:
            self._reported[t.track_id] = self._judged_reported(t)
        return self._reported[t.track_id]

    def _judged_reported(self, t: Track) -> bool:
        """A confirmed track that still moves (or just lost its detection for a cycle or two): its filter has not
        stood since (``_stands``: with hysteresis), or it walked ``ONSET_STEPS`` steps from where it stood, and its
        report window goes somewhere at a walker's speed (the speed from its last stand on), both as placed and with
        each fitted centre moved by its radius's change; a window younger than 0.5 s on its confirmation, unless its
        fits' change of radius accounts for more of its displacement than the body's own (:func:`_fit_moved_less`)."""
        c = self.config
        if not (t.confirmed and self.recently_seen(t) and t.speed_mps >= c.report_min_speed_mps):
            return False
        rows = np.array(t.recent)
        raw = rows[:, :4]
        if not self._steady(raw, raw[:, 3], t.seen_as_person):
            return False
        if raw[-1, 0] - raw[0, 0] < 0.5:
            return _fit_moved_less(raw, _report_rows(t.recent, turned=True))
        # the detections must move both as placed and with each fitted centre moved by its radius's change
        views = (raw, _report_rows(t.recent))
        start = self._walk_start(t.recent)
        if start is None:
            return False
        if start and not all(self._walks_off(rec[start:], rows[start:, 7]) for rec in views):
            return False
        return all(self._moves(rec, t.seen_as_person, start) for rec in views)

    @staticmethod
    def _walk_start(recent: list[tuple[float, ...]]) -> int | None:
        """Where the walk judged by the report window's speed starts: at the last detection with which the
        confirmed track's filter stood, for two detections in a row at least (a change point: the track stood
        there and moves now), else at the window's first; None while fewer than ``ONSET_STEPS`` steps between
        detections of one kind followed that stand (two steps of one point define a direction; a lone leg and a
        pair's midpoint, one step each, do not; one detection of a standing person whose composition changed, a
        leg paired with a piece 0.25 m off, is a jump, not a walk). The detections from before the stand would
        outvote a start: a walker who stood for 0.8 s of the window was reported 0.1 s after the window from its
        stand showed the walk."""
        # a stand lasts: two detections in a row (a walker turning back passes through zero speed in one)
        stood = [i for i, row in enumerate(recent) if row[6] and (i == 0 or recent[i - 1][6])]
        if not stood:
            return 0
        walk = recent[stood[-1]:]
        # a lone leg and a pair's midpoint are different points of a person: a direction is two steps of one of them
        kinds = [row[3] for row in walk]
        steps = max(kinds.count(k) for k in set(kinds)) - 1
        return stood[-1] if steps >= ONSET_STEPS else None

    @staticmethod
    def _point_noise_m(t: Track, det: Detection) -> float:
        """A detection's noise about the point of the body its kind sees (a pair's midpoint, a lone leg, a fitted
        centre): its own, a person's lone leg being either leg (``KIND_CHANGE_M``), a partly hidden one placed
        within half a radius. The offset between kinds is not in it (:func:`kind_aligned` fits it)."""
        sigma = DEFAULT_SIGMA_M if det.sigma_m is None else det.sigma_m
        extra = KIND_CHANGE_M if det.kind == "leg" and t.seen_as_person else 0.0
        if det.occluded:
            extra = math.hypot(extra, 0.5 * t.radius_m)
        return math.hypot(sigma, extra)

    def _walks_off(self, rows: np.ndarray, noise_m: np.ndarray) -> bool:
        """The detections since the stand, (stamp_s, x_m, y_m, kind) ``rows`` with their noise ``noise_m``, move
        faster than ``report_window_speed_mps`` by one standard error of their least-squares speed (weighted by
        each one's noise, an offset per kind): three leg pairs of a start (0.15 m in 0.2 s) do, three pairs of a
        standing person, 7 cm apart as its seen legs change, do not."""
        v, info = _kind_fit(rows[:, 0], rows[:, 1:3], rows[:, 3], 1.0 / noise_m**2)
        if info <= 0.0:
            return False
        return math.hypot(*v) - 1.0 / math.sqrt(info) >= self.config.report_window_speed_mps

    def _moves(self, rec: np.ndarray, person: bool, start: int = 0) -> bool:
        """The report window's (stamp_s, x_m, y_m, kind) rows go somewhere at a walker's speed: its path
        (straight enough) and, from row ``start`` on (a walk since the track last stood), its speed."""
        c = self.config
        path = self._window_path(rec, person)
        if path is None:
            return False
        parts, v = path
        if start > 0:
            v = kind_aligned(rec[start:])[1]
        # back and forth, over the window or its newest part: a standing body's detection jumping
        # between legs and wall, or a walker who stopped half a window ago
        for part in parts:
            step = np.hypot(*np.diff(part, axis=0).T)
            if float(np.hypot(*(part[-1] - part[0]))) < REPORT_STRAIGHTNESS * float(step.sum()):
                return False
        return math.hypot(*v) >= c.report_window_speed_mps

    def _window_path(self, rec: np.ndarray, person: bool) -> tuple[list[np.ndarray], tuple[float, float]] | None:
        """The report window's positions (kinds aligned) and its newest part, and its velocity; None when
        a person's newest leg-pair midpoints do not cover a walker's speed. For a person (``person``),
        a lone leg is either leg, ahead of the pelvis or behind it: no point of a path (two lone legs in
        a row, front then back, read as a step back). The pair's midpoints
        alone while the pair is what is seen now (3 of the newest detections; a person who stopped with
        the legs apart and is seen by one leg keeps the kinds aligned); they must also cover the
        window's speed (a few centimetres of midpoint jitter after the person stopped are "straight"
        too), with an offset per kind: a round body's fitted centre among them is another point of the person
        (a standing person's other leg seen as a leg-sized fit lies 0.23 m from its pairs' midpoints)."""
        c = self.config
        xy, v = kind_aligned(rec)
        parts = [xy, xy[-c.report_recent :]]
        if not person:
            return parts, v
        pair = rec[:, 3] != _KIND_CODE["leg"]
        newest = rec[-c.report_recent :][pair[-c.report_recent :]]
        if newest.shape[0] < 3:
            return parts, v
        covered = kind_aligned(newest)[0]
        if float(np.hypot(*(covered[-1] - covered[0]))) < c.report_window_speed_mps * np.ptp(newest[:, 0]):
            return None
        parts[1] = newest[:, 1:3]
        if np.ptp(rec[pair, 0]) >= 0.5:
            parts[0], v = kind_aligned(rec[pair])
        return parts, v

    def drop_seen_free(self, seen_free: Any, returns_xy: np.ndarray | None = None) -> None:
        """Drop coasting tracks whose predicted centre a beam of the current scan passed through, except
        a confirmed person's while one of the scan's returns (``returns_xy``, world frame, k x 2) lies
        where a leg could stand: a person's centre lies between the legs, where beams pass, and a leg
        split by a dropped return is no body but still there (a walker missed for one scan was dropped
        and started afresh, unreported for 3 cycles)."""
        pts = np.zeros((0, 2)) if returns_xy is None else returns_xy[np.all(np.isfinite(returns_xy), axis=1)]

        def gone(t: Track) -> bool:
            x, y = float(t.state[0]), float(t.state[1])
            if not seen_free(x, y):
                return False
            if not (t.confirmed and t.seen_as_person):
                return True  # (kept near returns, a chair's legs taken for a person would live on)
            # a person's legs stand up to half the widest pair from the centre
            reach = max(t.radius_m, KIND_CHANGE_M)
            return not bool(np.any(np.hypot(pts[:, 0] - x, pts[:, 1] - y) <= reach))

        self.tracks = [t for t in self.tracks if t.missed == 0 or not gone(t)]

    def _chain_back(self, stamp_s: float, det: Detection) -> list[tuple[float, Detection]]:
        """The body's detections in the kept earlier cycles, oldest first: from ``det`` back, the
        nearest one within a walker's step of the last found, each taken out of the memory (it starts
        no other track). Up to ``tentative_max_missed_s`` without one are passed over (a table leg
        unseen for two scans), as a coasting track would, but the reach stays one cycle's step: what
        jumped further in the gap is not known to be the same body. A partly occluded detection ends the
        chain: a body's or a lone leg's centre, placed behind the visible part, follows the occluder's
        edge (a leg pair's is good to 4 cm, ``_remember``, but ends it too: not re-measured). A
        detection a live track took is that track's body, not this one's past (a post's, tracked, when a
        table leg 0.26 m from it came out from behind a passing body: the leg "walked" from the post)."""
        c = self.config
        chain: list[tuple[float, Detection]] = []
        head_s, head = stamp_s, det
        missed = 0
        live = {t.track_id for t in self.tracks}
        for past_s, dets in reversed(self._past):
            reach = c.max_speed_mps * (head_s - past_s) / (missed + 1) + c.step_noise_m
            near, blocked = [], False
            for i, (d, holder) in enumerate(dets):
                if holder in live:
                    continue
                slack = _kind_slack_m(d, head, KIND_CHANGE_M)
                dist = math.hypot(d.x_m - head.x_m, d.y_m - head.y_m) - slack
                if dist > reach:
                    continue
                if d.occluded:
                    blocked = True
                else:
                    near.append((dist, i))
            if not near:
                missed += 1
                if blocked or head_s - past_s > c.tentative_max_missed_s + _STAMP_TOL_S:
                    break
                continue
            missed = 0
            head_s, head = past_s, dets.pop(min(near)[1])[0]
            chain.append((head_s, head))
        return chain[::-1]

    def _start(self, stamp_s: float, det: Detection) -> Track:
        """A new track from a detection with motion evidence, run through its body's earlier detections
        (remembered, not judged: confirmation comes at the earliest with the next cycle's detection)."""
        chain = self._chain_back(stamp_s, det) + [(stamp_s, det)]
        t0_s, d0 = chain[0]
        sigma = DEFAULT_SIGMA_M if d0.sigma_m is None else d0.sigma_m
        p = np.diag([sigma**2] * 2 + [self.config.init_speed_sigma_mps**2] * 2)
        track = Track(self._next_id, np.array([d0.x_m, d0.y_m, 0.0, 0.0]), p, d0.radius_m, t0_s,
                      evidence=int(d0.evidence), kind=d0.kind, born_s=t0_s, seen_s=t0_s, fits=int(d0.radius_fitted))
        self._next_id += 1
        n = len(self.config.accel_sigmas_mps2)
        # the leg offset: not yet seen (``_fresh_offset``)
        track.model_states, track.model_covs = _fresh_offset(np.tile(np.r_[track.state, 0.0, 0.0], (n, 1)),
                                                             np.tile(np.pad(p, (0, _N_STATE - 4)), (n, 1, 1)))
        track.model_probs = np.full(n, 1.0 / n)
        self._remember(track, d0)
        for t_s, d in chain[1:]:
            self._predict(track, t_s)
            self._fold(track, d)
            track.age_cycles += 1
        # the report window judges whether the body moves now: it starts where motion was first seen
        # (the earlier stretch may be the body standing before it started, e.g. the paper's cylinder)
        del track.recent[:-1]
        return track

    def step(self, stamp_s: float, detections: list[Detection]) -> list[tuple[Track, Detection | None]]:
        """Advance all tracks to ``stamp_s`` and fold in the detections. Returns the live tracks with
        the detection each received (None when coasting)."""
        self._reported.clear()
        while self._past and stamp_s - self._past[0][0] > self.config.retro_s + _STAMP_TOL_S:
            self._past.popleft()
        for t in self.tracks:
            self._predict(t, stamp_s)
        got, taken = self._associate(detections)
        for ti, t in enumerate(self.tracks):
            t.age_cycles += 1
            if ti in got:
                self._fold(t, got[ti])
                t.missed = 0
                self._confirm(t, detections, got[ti])
            else:
                t.missed += 1
        # for later chains: what no confirmed track holds (an unconfirmed one may die, and a track born
        # where it was should see the same static past, not start afresh with a short window)
        held = {i for i, ti in taken.items() if self.tracks[ti].confirmed}
        holder = {i: self.tracks[ti].track_id for i, ti in taken.items()}
        used = set(taken)
        born = set()
        for d in detections:
            if id(d) in used or not d.evidence:
                continue  # only motion evidence starts a track
            born.add(id(d))
            self.tracks.append(self._start(stamp_s, d))
            got[len(self.tracks) - 1] = d
        kept = [d for d in detections if id(d) not in held and id(d) not in born]
        self._past.append((stamp_s, [(d, holder.get(id(d))) for d in kept]))
        return self._prune(got)

    def _associate(self, detections: list[Detection]) -> tuple[dict[int, Detection], dict[int, int]]:
        """Track index -> its detection: nearest pairs first, each within the track's gate; and the id of each
        detection taken -> its track's index (a person's two lone legs measured as one, ``_other_leg``)."""
        pairs: list[tuple[float, int, int]] = []
        for ti, t in enumerate(self.tracks):
            for di, d in enumerate(detections):
                dist = math.hypot(d.x_m - t.state[0], d.y_m - t.state[1])
                gate = self.config.gate_m
                if not t.missed or (d.evidence and t.confirmed):
                    # a coasting track's covariance grows with the manoeuvres the body might have made; a
                    # detection that far off is the body only if it shows motion (else it is likely the
                    # furniture the track's prediction drifted onto), and only for a track that has shown
                    # it moves: an unconfirmed one (a table leg a passer-by uncovered) took the next
                    # table leg 0.6 m away and "walked" at 1.7 m/s
                    gate += 2.0 * math.sqrt(max(t.cov[0, 0] + t.cov[1, 1], 0.0))
                if dist < gate and not self._relocks(t, d):
                    pairs.append((dist, ti, di))
        pairs.sort()
        used_t: set[int] = set()
        used_d: set[int] = set()
        got: dict[int, Detection] = {}
        for _, ti, di in pairs:
            if ti in used_t or di in used_d:
                continue
            used_t.add(ti)
            used_d.add(di)
            got[ti] = detections[di]
        taken = {id(d): ti for ti, d in got.items()}
        for ti, d in list(got.items()):
            other = self._other_leg(self.tracks[ti], d, detections, used_d) if d.kind == "leg" else None
            if other is not None:
                used_d.add(other)
                taken[id(detections[other])] = ti
                got[ti] = _pair_of(d, detections[other], DEFAULT_SIGMA_M)
        return got, taken

    def _relocks(self, t: Track, d: Detection) -> bool:
        """``d`` is something else that stood where it is before the confirmed track came: no motion evidence,
        its place held when the laser last saw it (``Detection.held``), and outside the footprint of the
        track's body, where the returns may be the body's own: around the predicted centre and each of the
        track's last ``report_window`` detections, a person's legs up to ``KIND_CHANGE_M`` from its centre (a
        leg pair's midpoint), a lone leg's other leg up to a pair's width (``2 KIND_CHANGE_M``) from it, a round
        body's outline its radius from its centre; each plus ``confirm_vacated_m`` (a leg's width plus its
        jitter). A confirmed track that takes it re-locks onto the static background beside its body (a wall's
        piece, a table leg) and is reported reading the hop there as motion (an unconfirmed one is not
        confirmed on it: the place it left is not vacated, ``_left``)."""
        if d.evidence or not d.held or not t.confirmed:
            return False
        person = t.seen_as_person or t.kind != "body"
        own = np.array(t.recent)
        xy = np.vstack([own[:, 1:3], t.state[:2]])
        reach = np.append(np.where(own[:, 3] == _KIND_CODE["leg"], 2.0 * KIND_CHANGE_M,
                                   np.where(own[:, 3] == _KIND_CODE["person"], KIND_CHANGE_M, t.radius_m)),
                          KIND_CHANGE_M if person else t.radius_m)
        dist = np.hypot(xy[:, 0] - d.x_m, xy[:, 1] - d.y_m)
        return bool(np.all(dist > reach + self.config.confirm_vacated_m))

    def _other_leg(self, t: Track, leg: Detection, detections: list[Detection], used: set[int]) -> int | None:
        """The index of the track's other leg, seen as a lone leg of its own beside ``leg`` (the body stage
        pairs legs only up to its widest pair, and a pair at that limit splits in some scans): a free lone
        leg within a pair's reach (``2 KIND_CHANGE_M``) of ``leg`` that stands where one of the track's legs
        stood in its last ``confirm_window`` detections, to within ``step_noise_m``: where the track took a
        lone leg, or the partner of ``leg`` in a leg pair the track took (the pair's midpoint is then the two
        legs' midpoint); and their midpoint lies within ``gate_m`` of the prediction. A person seen by both
        legs is where their midpoint is: the two lone legs of a wide stance or a static pair (a chair's)
        taken one at a time read as a stride (a track that took the one, then the other 0.64 m away, was
        reported as moving). A static leg beside a walker's path stood where none of the walker's legs did."""
        c = self.config
        h = np.array(t.history)
        if not t.seen_as_person or h.size == 0:
            return None
        lone = h[h[:, 4] == _KIND_CODE["leg"], 1:3]
        pairs = h[h[:, 4] == _KIND_CODE["person"], 1:3]
        best: tuple[float, int] | None = None
        for di, o in enumerate(detections):
            if di in used or o.kind != "leg" or o is leg:
                continue
            sep = math.hypot(o.x_m - leg.x_m, o.y_m - leg.y_m)
            mid = np.array([0.5 * (o.x_m + leg.x_m), 0.5 * (o.y_m + leg.y_m)])
            stood = bool(np.any(np.hypot(*(lone - (o.x_m, o.y_m)).T) <= c.step_noise_m)
                         or np.any(np.hypot(*(pairs - mid).T) <= 0.5 * c.step_noise_m))
            if (stood and c.step_noise_m < sep <= 2.0 * KIND_CHANGE_M
                    and math.hypot(mid[0] - t.state[0], mid[1] - t.state[1]) < c.gate_m
                    and (best is None or sep < best[0])):
                best = (sep, di)
        return None if best is None else best[1]

    def _prune(self, got: dict[int, Detection]) -> list[tuple[Track, Detection | None]]:
        """Drop the dead (missed too long, tentative too old, space seen free) and the duplicates of
        older tracks, then bound the number: the confirmed first, then the best supported."""
        out: list[tuple[Track, Detection | None]] = []
        keep: list[Track] = []
        c = self.config
        for ti, t in enumerate(self.tracks):
            too_old = not t.confirmed and t.stamp_s - t.born_s >= c.tentative_max_age_s - _STAMP_TOL_S
            max_missed_s = c.max_missed_s if t.confirmed else c.tentative_max_missed_s
            if self.unseen_s(t) > max_missed_s + _STAMP_TOL_S or too_old or self._stale(t):
                continue
            if any(math.hypot(k.state[0] - t.state[0], k.state[1] - t.state[1]) < self.merge_m for k in keep):
                continue  # a duplicate of an older track (tracks are kept oldest first)
            keep.append(t)
            out.append((t, got.get(ti)))
        if len(keep) > c.max_tracks:
            ranked = sorted(keep, key=lambda t: (not t.confirmed, -t.evidence, t.missed, -t.hits))
            alive = {id(t) for t in ranked[: c.max_tracks]}
            keep = [t for t in keep if id(t) in alive]
            out = [(t, d) for t, d in out if id(t) in alive]
        self.tracks = keep
        return out
