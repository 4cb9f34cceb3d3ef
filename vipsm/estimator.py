"""The VIPSM estimator: one object with explicit state, ``step(scan, odometry, frame) -> Estimate``.

``step`` is the paper's pipeline (Fig. 5) with the product's additions, one stage per line:

1. laser pre-filter (:mod:`vipsm.prefilter`): mixed pixels and lone returns dropped;
2. visual bearings (:mod:`vipsm.flow`): optical flow with the robot's own motion removed gives the
   bearing intervals of independently moving things, in the laser frame at the scan's stamp;
3. restoration (:mod:`vipsm.restore`): segments in those directions, and where tracked bodies are
   predicted, are cut and bridged with weight 0 (the plain-PSM baseline skips this step);
4. matching (:mod:`vipsm.keyframes`, :mod:`vipsm.psm`): PSM against a keyframe, seeded by odometry;
5. body extraction (:mod:`vipsm.bodies`): foreground segments that moved into space the laser saw
   free (:mod:`vipsm.static_map`, confirmed at beam resolution by :mod:`vipsm.seen_through`) or that
   the camera saw move; legs paired into people;
6. tracking (:mod:`vipsm.tracker`): constant-velocity Kalman tracks, reported once confirmed;
7. static evidence: the scan is added to the free/occupied grid, tracks whose space is now seen free
   are dropped.

Where the camera and the laser disagree: the laser's evidence decides whether something is a moving
body (a flow blob on furniture that never moves never confirms a track; the camera cannot see a body
coming head-on), the camera decides early (a slow body confirms as soon as it has moved a few
centimetres, long before it leaves its own footprint in the free-space grid) and, as in the paper,
keeps the moving body out of the scan matcher.

Frames: ``Estimate.pose`` is the robot pose in the odometry frame (the first estimate equals the
first odometry pose); obstacle positions/velocities are in that frame too. Only confirmed, moving
tracks are reported in ``Estimate.obstacles`` (and so can stop the robot).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field, replace

import cv2
import numpy as np
from numba import njit

from .bodies import BodiesConfig, Body, Derived, derive, extract_bodies
from .flow import CameraMount, FlowConfig, FlowDetector, interval_to_laser, pose_at
from .geometry import between, compose, scan_points, wrap_angle
from .identity import ObstacleIdentity
from .keyframes import KeyframeMatcher, MatchOutcome
from .legs import LegModel
from .motion import ConstantVelocity, Twist2D, deskew, laser_twist
from .people import LegDetection, PeopleConfig, PeopleTracker, detect_legs
from .prefilter import PrefilterConfig, ramp_masks, veiling_masks
from .psm import PsmConfig, prepare_scan
from .restore import BearingInterval, Restoration, RestoreConfig, restore
from .seen_through import ScanMemory, SeenThroughConfig
from .sensor import SelfReturns
from .static_map import FreeSpaceGrid, StaticMapConfig
from .tracker import Detection, Track, Tracker, TrackerConfig
from .types import Estimate, EstimateFlag, Frame, Obstacle, Odometry, Pose2D, Scan


def _estimator_psm() -> PsmConfig:
    # Odometry-seeded scan-to-keyframe matching at 10 Hz: a +-7.5 deg first orientation search and
    # +-2.5 deg later ones are ample (the keyframe is at most ~10 deg away and the odometry's heading
    # error is far smaller) and cut the cost; two small steps in a row end the iterations.
    # A 3-beam median, not the original's 5: on a noisy range profile the median pushes a thin object
    # back by an amount that shrinks as the robot comes closer and the object covers more beams (a
    # 44 mm table leg 12 mm at 3.5 m, 2 mm at 1 m with window 5; 4 and 1.5 mm with 3), so furniture
    # seemed to approach faster than the robot drove: the furnished room's forward drift (docs/
    # estimator.md, "The matcher's median"). Spikes are the pre-filter's and the segmentation's job.
    # The windows are angles (30 and 10 beams of the UTM-30LX's 0.25 deg), so a coarser scanner searches
    # the same angle. The refinement (run without odometry only, ``no_odometry_refine_iterations``) is the
    # two-way point-to-line cost: on the real Intel and CSAIL pairs it beats the one-sided fit, and on the
    # leg_tracker drive it brings every laser's path nearer an independent registration.
    return PsmConfig(search_window_first_rad=math.radians(7.5), search_window_rad=math.radians(2.5), stop_count=2,
                     median_window=3, refine_symmetric=True)


MOTION_PRIORS = ("odometry", "constant_velocity")
DESKEW_MODES = ("off", "no_odometry", "always")


@dataclass(frozen=True)
class EstimatorConfig:
    # Mount poses on the robot (robot frame: x forward, y left, z up).
    laser_x_m: float = 0.0
    laser_y_m: float = 0.0
    laser_theta_rad: float = 0.0
    camera_x_m: float = 0.0
    camera_y_m: float = 0.0
    camera_z_m: float = 1.0
    psm: PsmConfig = field(default_factory=_estimator_psm)
    restore: RestoreConfig = field(default_factory=RestoreConfig)
    flow: FlowConfig = field(default_factory=FlowConfig)
    tracker: TrackerConfig = field(default_factory=TrackerConfig)
    prefilter: PrefilterConfig = field(default_factory=PrefilterConfig)
    static_map: StaticMapConfig = field(default_factory=StaticMapConfig)
    seen_through: SeenThroughConfig = field(default_factory=SeenThroughConfig)
    bodies: BodiesConfig = field(default_factory=BodiesConfig)
    people: PeopleConfig = field(default_factory=PeopleConfig)
    keyframe_dist_m: float = 0.30
    keyframe_angle_rad: float = math.radians(10.0)
    keyframe_min_overlap: float = 0.60
    keyframe_stale_dist_m: float = 0.60
    max_frame_age_s: float = 0.25  # a frame further than this from the scan's stamp is not used
    track_mask_margin_m: float = 0.15  # added to a track's radius for its predicted interval
    ahead_min_m: float = 0.05  # a return this far in front of the keyframe's in its direction is motion evidence
    max_correction_m: float = 0.5  # a match further than this from the odometry prediction is refused
    max_correction_rad: float = math.radians(20.0)
    weak_info: float = 0.08  # normalised translation information below which odometry is blended in
    weak_info_min: float = 0.03  # ... and below which the odometry's translation is kept entirely
    odom_sigma_per_m: float = 0.05  # covariance growth on odometry fallback
    odom_sigma_rad_per_rad: float = 0.05
    #: what seeds each match: "odometry" (the wheels' motion since the last scan) or "constant_velocity"
    #: (the last estimated motion again: for a robot without odometry; ``step(scan, None)`` does the same)
    motion_prior: str = "odometry"
    #: a refused match is retried against the keyframe with the orientation search widened to this and the
    #: first iterations' residual gate to ``recovery_max_error_m``, then against the previous keyframe and
    #: the last scan; a retry may correct the prediction by up to ``recovery_max_correction_*``
    recovery_window_rad: float = math.radians(30.0)
    recovery_max_error_m: float = 1.0
    recovery_max_correction_m: float = 1.0
    recovery_max_correction_rad: float = math.radians(45.0)
    #: the constant-velocity prediction does not extrapolate across a longer gap between scans
    max_prediction_gap_s: float = 1.0
    #: without odometry, point-to-line steps finish each match (``psm.refine_iterations`` with odometry):
    #: there every match error stays in the path (no odometry to blend with), and on the leg_tracker drive
    #: these steps halve the distance to an independent registration on two of its three lasers; with
    #: odometry the simulated suite's obstacle errors grow with them (paper2 0.008 -> 0.013 m), so they
    #: are off there by default
    no_odometry_refine_iterations: int = 5
    #: the scan the matcher sees is de-skewed: each return moved by the laser's motion since the first beam
    #: (``Scan.beam_dt_s``; the motion is the odometry's twist, without odometry the constant-velocity
    #: model's), see :func:`vipsm.motion.deskew`. "off", "no_odometry" (only without odometry) or "always"
    deskew: str = "no_odometry"
    #: beams that see the robot itself are cut from every stage (:class:`vipsm.sensor.SelfReturns`): the
    #: robot's footprint along each beam, learned at checks ``self_returns_turn_rad`` of turn apart: a
    #: (beam, range within ``self_returns_tol_m``) held in ``self_returns_share`` of the checks that could
    #: see it, by at least ``self_returns_checks`` of them, out to ``self_returns_max_range_m`` (the robot's
    #: reach from its laser). ``self_returns_turn_rad`` 0: off
    self_returns_turn_rad: float = math.radians(30.0)
    self_returns_tol_m: float = 0.05
    self_returns_checks: int = 2
    self_returns_max_range_m: float = 1.0
    self_returns_share: float = 0.5
    #: the laser's travel is evidence too: checks also every ``self_returns_move_m`` of travel, where a return
    #: whose world point the last check's scan saw through (it moved with the laser) and that the beam held
    #: steady since counts as the robot's, and one that scan saw (a static surface, also a wall parallel to the
    #: travel) as not. Must exceed ``2 self_returns_tol_m`` (the static test's margin); 0: turns only
    self_returns_move_m: float = 0.2
    #: bodies, tracking and the static map run at most this often (their thresholds count cycles of
    #: this length); scans in between publish the tracks predicted to their stamp
    obstacle_period_s: float = 0.1

    def __post_init__(self) -> None:
        if self.no_odometry_refine_iterations < 0:
            raise ValueError(f"no_odometry_refine_iterations must be >= 0, got {self.no_odometry_refine_iterations}")
        if (self.self_returns_turn_rad < 0.0 or not self.self_returns_tol_m > 0.0 or self.self_returns_checks < 1
                or not self.self_returns_max_range_m > self.self_returns_tol_m
                or not 0.0 < self.self_returns_share <= 1.0
                or not (self.self_returns_move_m == 0.0 or self.self_returns_move_m > 2.0 * self.self_returns_tol_m)):
            raise ValueError("need self_returns_turn_rad >= 0 (0: off), self_returns_tol_m > 0, self_returns_checks "
                             ">= 1, self_returns_max_range_m > self_returns_tol_m, 0 < self_returns_share <= 1 and "
                             "self_returns_move_m 0 (off) or > 2 self_returns_tol_m")
        if self.deskew not in DESKEW_MODES:
            raise ValueError(f"deskew must be one of {', '.join(DESKEW_MODES)}, got {self.deskew!r}")
        if self.motion_prior not in MOTION_PRIORS:
            raise ValueError(f"motion_prior must be one of {', '.join(MOTION_PRIORS)}, got {self.motion_prior!r}")
        self.bodies_derived  # noqa: B018 (raises when the derived body quantities are inconsistent)

    @property
    def laser_mount(self) -> Pose2D:
        return Pose2D(self.laser_x_m, self.laser_y_m, self.laser_theta_rad)

    @property
    def bodies_derived(self) -> Derived:
        """The body stage's quantities taken from the people, tracker, flow and static map keys."""
        return derive(self.bodies, self.people, self.tracker, self.flow.baseline_s, self.static_map.cell_m)

    @property
    def camera_mount(self) -> CameraMount:
        return CameraMount(self.camera_x_m, self.camera_y_m, self.camera_z_m)


@dataclass(frozen=True)
class StepDebug:
    """What the last step saw (for plots and diagnostics; not part of the Estimate contract)."""

    intervals: tuple[BearingInterval, ...]
    restoration: Restoration | None
    match: MatchOutcome
    bodies: tuple[Body, ...]


#: measurement noise per kind of detection: a leg-pair midpoint jitters with the gait (~5 cm), a lone
#: leg is a hip's half-width off the body centre, a circle fit on a large body is good to 2-3 cm
_SIGMA_M = {"person": 0.06, "leg": 0.12, "body": 0.03}
#: ... across a walker's path: the midpoint of the two legs moves stop-and-go along the path with the
#: alternating steps, sideways only with the pelvis's sway (its mediolateral excursion is ~4-5 cm peak
#: to peak in level walking)
_SIGMA_ACROSS_M = {"person": 0.025}


class Estimator:
    """VIPSM (``plain_psm=False``) or the plain-PSM baseline (``plain_psm=True``) on the same code."""

    def __init__(self, config: EstimatorConfig | None = None, plain_psm: bool = False,
                 leg_model: LegModel | None = None) -> None:
        """``leg_model`` (``app.legmodel.default_leg_model()``): the people stage's leg detector; without
        it the stage is off and ``Estimate.people`` stays empty (the estimator reads no files)."""
        self.config = config or EstimatorConfig()
        self.plain_psm = plain_psm
        cfg = self.config
        self._flow = FlowDetector(cfg.flow, cfg.camera_mount)
        self._memory = ScanMemory(cfg.seen_through)
        self._tracker = Tracker(cfg.tracker, self._memory, cfg.people)
        self._people = PeopleTracker(cfg.people, leg_model) if leg_model is not None else None
        # one obstacle id per person across the two trackers and across a body track lost and found again
        self._identity = ObstacleIdentity(cfg.people.person_radius_m, cfg.tracker.max_missed_s,
                                          cfg.tracker.max_speed_mps, cfg.tracker.step_noise_m)
        self._matcher = KeyframeMatcher(cfg)
        self._static = FreeSpaceGrid(cfg.static_map)
        self._bodies_derived = cfg.bodies_derived
        self._last_pose: Pose2D | None = None
        self._last_obstacle_s: float | None = None
        self._last_odo: Pose2D | None = None
        self._motion = ConstantVelocity(self.config.max_prediction_gap_s)
        c = self.config
        self._self_returns = (SelfReturns(c.self_returns_turn_rad, c.self_returns_tol_m, c.self_returns_checks,
                                          max_range_m=c.self_returns_max_range_m, min_share=c.self_returns_share,
                                          move_m=c.self_returns_move_m)
                              if c.self_returns_turn_rad > 0.0 else None)
        self._last_cov = np.zeros((3, 3))
        self.last_debug: StepDebug | None = None
        self._deskew_w_radps = 0.0  # the turn rate the last de-skew assumed (0: not de-skewed)
        self._skew_rad = 0.0  # the heading error the sweep's skew left in this cycle's scan (see _skew_left)
        self._heading_sigma_rad: float | None = None  # this cycle's own heading error (see _heading_sigma)

    # ------------------------------------------------------------------ the pipeline
    def step(self, scan: Scan, odometry: Odometry | None, frame: Frame | None = None) -> Estimate:
        """One cycle. ``odometry`` None (or ``motion_prior`` "constant_velocity"): no odometry, each match
        is seeded by the last estimated motion (:mod:`vipsm.motion`)."""
        flags = EstimateFlag.PLAIN_PSM if self.plain_psm else EstimateFlag.NONE
        scan, scan_ok = _checked(scan)
        scan, lone_m, dropped = self._prefilter(scan)
        odometry, predicted, given = self._prior(scan.stamp_s, odometry)
        scan, lone_m, dropped = self._without_self_returns(scan, lone_m, dropped, predicted)
        scan, lone_m = self._deskewed(scan, lone_m, odometry, given)
        camera, flags = self._visual_bearings(scan, odometry, frame, flags)
        masks = camera + self._track_masks(scan.stamp_s, predicted)
        rest = restore(scan.ranges_m, scan.bearings_rad, masks, self.config.restore, self.config.psm.min_range_m)
        match = self._match(scan, rest, predicted, scan_ok, not given)
        if not given and match.flags & EstimateFlag.ODOMETRY_FALLBACK:
            flags |= EstimateFlag.POSE_UNCERTAIN
        laser = compose(match.pose, self.config.laser_mount)
        self._skew_rad = self._skew_left(scan, match)
        self._heading_sigma_rad = self._heading_sigma(match)
        self._memory.observe(laser, self._heading_sigma_rad)
        bodies, tracked = self._obstacles(scan, lone_m, dropped, laser, camera, match)
        self.last_debug = StepDebug(tuple(masks), rest, match, tuple(bodies))
        return self._estimate(scan, odometry if given else None, match, rest,
                              flags | match.flags | _rest_flags(rest, self.plain_psm), tracked, laser)

    # ------------------------------------------------------------------ stages
    def _obstacles(self, scan: Scan, lone_m: np.ndarray, dropped: np.ndarray, laser: Pose2D,
                   camera: list[BearingInterval], match: MatchOutcome
                   ) -> tuple[list[Body], list[tuple[Track, Detection | None]]]:
        """Bodies, tracking and the static map at most every ``obstacle_period_s`` (the cycle their
        thresholds are counted in); a scan in between (the 40 Hz loop) publishes the tracks predicted
        to its stamp. ``lone_m``: the lone returns the pre-filter dropped (NaN elsewhere), which the
        static map takes back; ``dropped``: every beam whose return the pre-filter removed."""
        last = self._last_obstacle_s
        if last is not None and scan.stamp_s - last < 0.8 * self.config.obstacle_period_s:
            return [], [(t, None) for t in self._tracker.tracks]
        self._last_obstacle_s = scan.stamp_s
        bodies = extract_bodies(scan.ranges_m, scan.bearings_rad, laser, self._static, camera, self.config.bodies,
                                self.config.tracker, self._ahead_of_keyframe(scan, match), self._memory, dropped,
                                self._bodies_derived,
                                self._people.known_legs(scan.stamp_s) if self._people is not None else None)
        sigma = self._heading_sigma_rad
        sigma = self.config.seen_through.heading_sigma_rad if sigma is None else sigma
        held = _held_before(self._static, laser, scan, bodies)
        tracked = self._tracker.step(scan.stamp_s, [_detection(b, laser, sigma, h) for b, h in zip(bodies, held)])
        if self._people is not None:
            # the leg detector's view also without the ramps of mixed pixels (stage 1's second rule)
            ramps = ramp_masks(scan.ranges_m, scan.bearings_rad, self.config.prefilter)
            legs = _with_evidence(detect_legs(np.where(ramps, np.nan, scan.ranges_m), scan.bearings_rad, laser,
                                              self._people.model, self.config.people, self.config.bodies,
                                              dropped | ramps), bodies)
            self._people.step(scan.stamp_s, legs, _visibility(scan, laser), _seen_through(scan, laser),
                              _returned_before(self._static, laser, self.config.people.leg_radius_m),
                              _returns_near(scan.bearings_rad, np.where(dropped, np.nan, scan.ranges_m), laser,
                                            self.config.people.person_radius_m),
                              _seen_before(self._memory, laser, self.config.people.leg_radius_m,
                                           scan.stamp_s - self.config.people.leg_memory_s))
        self._update_static(scan, lone_m, laser, bodies)
        return bodies, tracked

    def _without_self_returns(self, scan: Scan, lone_m: np.ndarray, dropped: np.ndarray, predicted: Pose2D
                              ) -> tuple[Scan, np.ndarray, np.ndarray]:
        """The scan without the beams that see the robot itself (they count as removed, like the pre-filter's).
        A beam on which a part of the robot was found is cut whole, also where it returns beyond that part: it
        is blocked by the robot in most scans, so what it returns past the part came by the part's edge or
        off its surface (a shiny frame sends the beam on to a robot-fixed echo at one range, which a turn
        sweeps through space the laser saw free), not from a surface straight along the beam."""
        if self._self_returns is None:
            return scan, lone_m, dropped
        laser = compose(predicted, self.config.laser_mount)
        own = self._self_returns.update(np.where(np.isfinite(lone_m), lone_m, scan.ranges_m), laser.theta_rad,
                                        scan.bearings_rad, (laser.x_m, laser.y_m))
        own = own | self._self_returns.found()
        if not own.any():
            return scan, lone_m, dropped
        ranges = np.where(own, np.nan, scan.ranges_m)
        scan = Scan(ranges, scan.bearings_rad, scan.stamp_s, scan.seq, scan.beam_dt_s, scan.intensities)
        return scan, np.where(own, np.nan, lone_m), dropped | own

    def _deskewed(self, scan: Scan, lone_m: np.ndarray, odometry: Odometry, given: bool) -> tuple[Scan, np.ndarray]:
        """The scan (and the lone returns) as seen from the laser's pose at the first beam (``deskew``): every
        stage of the cycle then places its beams with the one pose the matcher finds for the stamp."""
        cfg = self.config
        self._deskew_w_radps = 0.0
        if not (cfg.deskew == "always" or (cfg.deskew == "no_odometry" and not given)):
            return scan, lone_m
        tw = Twist2D(odometry.v_mps, 0.0, odometry.w_radps) if given else self._motion.twist
        tw = laser_twist(tw, cfg.laser_mount)
        self._deskew_w_radps = tw.w_radps
        jump, factor = cfg.psm.seg_jump_m, cfg.psm.seg_jump_range_factor
        ranges, _ = deskew(scan.ranges_m, scan.bearings_rad, scan.beam_dt_s, tw, jump, factor)
        lone, _ = deskew(lone_m, scan.bearings_rad, scan.beam_dt_s, tw, jump, factor)
        return Scan(ranges, scan.bearings_rad, scan.stamp_s, scan.seq, scan.beam_dt_s, scan.intensities), lone

    def _skew_left(self, scan: Scan, match: MatchOutcome) -> float:
        """The heading error the sweep's skew left in this scan: the last beam is seen ``sweep`` after the
        first, and a turn rate the de-skew did not assume (all of it without de-skew; the change since the
        last cycle with it) turns it by that rate times ``sweep``. The rate is the matched one since the
        last estimate."""
        last, since = self._last_pose, self._motion.stamp_s
        dt = scan.stamp_s - since if since is not None else 0.0
        if last is None or not 0.0 < dt <= self.config.max_prediction_gap_s:
            return 0.0
        w = math.remainder(match.pose.theta_rad - last.theta_rad, 2.0 * math.pi) / dt
        sweep_s = abs(scan.beam_dt_s) * max(scan.ranges_m.size - 1, 0)
        return abs(w - self._deskew_w_radps) * sweep_s

    def _heading_sigma(self, match: MatchOutcome) -> float | None:
        """This cycle's own heading error (1 sigma) beyond what the evidence tests' fixed tolerances hold
        (``seen_through.lateral_tol_m``, ``ahead_min_m`` already allow for a matched pose's few centimetres):
        the skew the sweep left; None where no match measured the pose (the evidence stages then take
        ``seen_through.heading_sigma_rad``)."""
        res = match.result
        if res is None or res.refused or EstimateFlag.ODOMETRY_FALLBACK in match.flags:
            return None
        return self._skew_rad

    def _prefilter(self, scan: Scan) -> tuple[Scan, np.ndarray, np.ndarray]:
        """The scan without mixed pixels and lone returns, the lone returns (NaN elsewhere), and the
        beams it removed."""
        mixed, lone = veiling_masks(scan.ranges_m, scan.bearings_rad, self.config.prefilter, ramps=False)
        ranges = np.where(mixed | lone, np.nan, scan.ranges_m)
        lone_m = np.where(lone, scan.ranges_m, np.nan)
        scan = Scan(ranges, scan.bearings_rad, scan.stamp_s, scan.seq, scan.beam_dt_s, scan.intensities)
        return scan, lone_m, mixed | lone

    def _prior(self, stamp_s: float, odometry: Odometry | None) -> tuple[Odometry, Pose2D, bool]:
        """(the odometry the stages use, the predicted pose, whether odometry was given). Without odometry
        the prediction is the constant-velocity model's, and the stages get it as a stand-in odometry (its
        pose and twist), so the camera's motion compensation works the same."""
        if odometry is not None and self.config.motion_prior == "odometry":
            return odometry, self._predict(odometry.pose), True
        pose = self._motion.predict(stamp_s)
        if pose is None:  # the first scan: the odometry frame is its pose (the origin without odometry)
            pose = odometry.pose if odometry is not None else Pose2D(0.0, 0.0, 0.0)
        tw = self._motion.twist
        return Odometry(pose.x_m, pose.y_m, pose.theta_rad, tw.vx_mps, tw.w_radps, stamp_s), pose, False

    def _predict(self, odo: Pose2D) -> Pose2D:
        if self._last_pose is None:
            return odo
        if self._last_odo is None:  # odometry again after cycles without: its motion from here on
            return self._last_pose
        return compose(self._last_pose, between(self._last_odo, odo))

    def _visual_bearings(self, scan: Scan, odometry: Odometry, frame: Frame | None, flags: EstimateFlag
                         ) -> tuple[list[BearingInterval], EstimateFlag]:
        """Bearing intervals of independent image motion (laser frame, at the scan's stamp)."""
        cfg = self.config
        if frame is None:
            return [], flags | EstimateFlag.NO_FRAME
        if abs(frame.stamp_s - scan.stamp_s) > cfg.max_frame_age_s:
            self._flow.reset()
            return [], flags | EstimateFlag.STALE_FRAME
        pose_f = pose_at(odometry, frame.stamp_s)
        # depth for the frame's pixels: this scan, moved into the robot frame at the frame's stamp
        pts = self._laser_to_robot_points(scan.ranges_m, scan.bearings_rad)
        rel_sf = between(pose_f, pose_at(odometry, scan.stamp_s))
        cs, sn = math.cos(rel_sf.theta_rad), math.sin(rel_sf.theta_rad)
        depth = np.stack([rel_sf.x_m + cs * pts[:, 0] - sn * pts[:, 1], rel_sf.y_m + sn * pts[:, 0] + cs * pts[:, 1]],
                         axis=1)
        try:
            fres = self._flow.detect(frame, pose_f, depth, odometry.v_mps, odometry.w_radps)
        except (cv2.error, ValueError):  # e.g. an image of the wrong dtype or shape
            self._flow.reset()
            return [], flags | EstimateFlag.FRAME_ERROR
        if fres is None:  # no earlier frame to compute the flow against
            return [], flags | EstimateFlag.NO_FLOW
        return [interval_to_laser(iv, rel_sf, cfg.laser_mount) for iv in fres.intervals], flags

    def _track_masks(self, stamp_s: float, predicted: Pose2D) -> list[BearingInterval]:
        """Where tracked bodies with motion evidence are predicted: cut from the scan the matcher sees."""
        out = []
        laser_world = compose(predicted, self.config.laser_mount)
        for t in self._tracker.tracks:
            if not (t.confirmed or t.evidence >= 1):
                continue
            wx, wy = self._tracker.predict_position(t, stamp_s)
            rel = between(laser_world, Pose2D(wx, wy, 0.0))
            d = math.hypot(rel.x_m, rel.y_m)
            half_w = t.radius_m + self.config.track_mask_margin_m
            if d <= half_w:
                continue
            b = math.atan2(rel.y_m, rel.x_m)
            half = math.asin(min(half_w / d, 1.0))
            # the body occupies these ranges too: what the laser sees beside or behind it is not cut
            out.append(BearingInterval(b - half, b + half, 0.0, 0.0, "track", t.track_id, d - half_w, d + half_w))
        return out

    def _match(self, scan: Scan, rest: Restoration, predicted: Pose2D, scan_ok: bool, no_odometry: bool
               ) -> MatchOutcome:
        cfg = self.config
        if self.plain_psm:
            cur = prepare_scan(scan.ranges_m, scan.bearings_rad, cfg.psm)
        else:
            cur = prepare_scan(rest.ranges_m, scan.bearings_rad, cfg.psm, rest.weights)
        n_good_w = int(np.count_nonzero(cur.good & (cur.weights > 0)))
        too_large = rest.too_large and not self.plain_psm
        return self._matcher.match(cur, n_good_w, predicted, self._last_pose, self._last_cov, not too_large,
                                   too_large or not scan_ok, scan.ranges_m.copy(), no_odometry,
                                   None if self.plain_psm else rest.ranges_m)

    def _update_static(self, scan: Scan, lone_m: np.ndarray, laser: Pose2D, bodies: list[Body]) -> None:
        """Add the scan to the free/occupied grid (the moving-body candidates add no occupancy, so a body
        that moves on leaves no trail and its own earlier footprint never hides it) and drop coasting
        tracks whose space is now seen free. The lone returns count: a chair leg a few metres away is
        often one return, and without it the beams beside it mark its cell free until, seen from
        nearer, it violates that free space."""
        skip = np.zeros(scan.ranges_m.size, bool)
        for b in bodies:
            if b.evidence:
                skip[b.scan_index_start : b.scan_index_stop] = True
        skip |= self._near_tracks(scan, laser)
        ranges = np.where(np.isfinite(lone_m), lone_m, scan.ranges_m)
        self._static.integrate(scan.stamp_s, (laser.x_m, laser.y_m), laser.theta_rad, ranges,
                               scan.bearings_rad, skip)
        self._memory.push(laser, ranges, scan.bearings_rad, self._heading_sigma_rad, scan.stamp_s)
        if any(t.missed for t in self._tracker.tracks):  # only a coasting track can be dropped
            self._tracker.drop_seen_free(self._static.seen_free_now, scan_points(laser, ranges, scan.bearings_rad))

    def _estimate(self, scan: Scan, odometry: Odometry | None, match: MatchOutcome, rest: Restoration,
                  flags: EstimateFlag, tracked: list[tuple[Track, Detection | None]], laser: Pose2D) -> Estimate:
        self._last_pose = Pose2D(match.pose.x_m, match.pose.y_m, wrap_angle(match.pose.theta_rad))
        self._last_odo = odometry.pose if odometry is not None else None
        self._motion.update(self._last_pose, scan.stamp_s)
        self._last_cov = match.cov
        at = self._tracker.predict_position
        tr = self._tracker
        # the body tracker's moving bodies: a moving person near one is that body, reported once (a confirmed
        # body it does not report does not hide a person the people stage sees walk: ``Tracker.moving``)
        obstacles = tuple(_obstacle(t, d, laser, at(t, scan.stamp_s)) for t, d in tr.moving(tracked))
        people = self._people.people(scan.stamp_s) if self._people is not None else ()
        persons, links, live = (), {}, set()
        if self._people is not None:
            links = self._people.bodies_standing_for(people, obstacles)
            persons = self._people.obstacles(people, obstacles, laser, links)
            live = {t.track_id for t in self._people.tracks}
        obstacles = self._identity.relabel(obstacles, persons, links, {t.track_id for t in tr.tracks}, live,
                                           scan.stamp_s)
        return Estimate(
            stamp_s=scan.stamp_s,
            pose=self._last_pose,
            covariance=match.cov,
            obstacles=obstacles,
            quality=match.quality,
            flags=flags,
            restored_indices=() if self.plain_psm else rest.cut,
            people=people,
        )

    # ------------------------------------------------------------------ helpers
    def _ahead_of_keyframe(self, scan: Scan, match: MatchOutcome) -> np.ndarray | None:
        """Per beam: the return stands at least ``ahead_min_m`` in front of what the keyframe (the
        reference scan, taken up to ``keyframe_dist_m`` back) saw in that direction. A static scene
        cannot do that (a new viewpoint only reveals surfaces behind what was seen); a body that
        moved towards the laser does. "In that direction" allows for the heading uncertainty between the
        keyframe and this scan (:meth:`ScanMemory.relative_heading_sigma_rad`): the return must stand in
        front of everything the keyframe saw within ``sigma_gate`` sigmas of its bearing, so the near side
        of a depth edge, seen a fraction of a degree off, is no motion."""
        kf = self._matcher.keyframe
        if kf is None or EstimateFlag.ODOMETRY_FALLBACK in match.flags:
            return None
        cfg = self.config
        rel = between(compose(kf.pose, cfg.laser_mount), compose(match.pose, cfg.laser_mount))
        r, b = scan.ranges_m, scan.bearings_rad
        valid = np.isfinite(r)
        rr = np.where(valid, r, 0.0)
        c, s = math.cos(rel.theta_rad), math.sin(rel.theta_rad)
        cos_b, sin_b = np.cos(b), np.sin(b)
        x = rel.x_m + c * rr * cos_b - s * rr * sin_b
        y = rel.y_m + s * rr * cos_b + c * rr * sin_b
        phi, rho = np.arctan2(y, x), np.hypot(x, y)
        kb = kf.prep.bearings_rad
        if kb.size < 3:
            return None
        j = np.clip(np.searchsorted(kb, phi), 1, kb.size - 1)
        j -= (np.abs(kb[j - 1] - phi) < np.abs(kb[j] - phi)).astype(np.intp)
        kr = np.where(kf.prep.good, kf.prep.ranges_m, np.nan)
        if kf.seen_m is not None:
            # where restoration bridged a cut (a body the camera or a track flagged, rightly or not) the
            # keyframe holds an interpolation between the surfaces beside it, not what the laser saw:
            # a box in front of that line would look "ahead" for as long as the keyframe lives.
            # There the measured range counts.
            kr = np.where(kf.prep.weights > 0.0, kr, kf.seen_m)
        kr = _nearest_within(kr, self._ahead_window_beams(kf.pose, match.pose, kb))[j]
        with np.errstate(invalid="ignore"):
            return valid & (phi >= kb[0]) & (phi <= kb[-1]) & (rho < kr - self._ahead_margin_m(match))

    def _ahead_margin_m(self, match: MatchOutcome) -> float:
        """How far in front of the keyframe a return must stand: ``ahead_min_m`` beyond what the two scans'
        range differences scatter by after this match (its mean absolute residual, 0.8 sigma for Gaussian
        noise, times ``seen_through.sigma_gate``): a noisier scanner, or a match that fits worse, needs a
        clearer step towards the laser."""
        res = match.result
        spread = res.residual_m / 0.8 if res is not None and math.isfinite(res.residual_m) else 0.0
        return self.config.ahead_min_m + self.config.seen_through.sigma_gate * spread

    def _ahead_window_beams(self, kf_pose: Pose2D, pose: Pose2D, kb: np.ndarray) -> int:
        """Keyframe beams either side that the heading uncertainty between it and ``pose`` reaches."""
        st = self.config.seen_through
        own = self._heading_sigma_rad if self._heading_sigma_rad is not None else st.heading_sigma_rad
        mount = self.config.laser_mount
        sigma = self._memory.relative_heading_sigma_rad(compose(kf_pose, mount), own, compose(pose, mount), own)
        step = float(abs(kb[-1] - kb[0]) / (kb.size - 1))
        return min(int(math.ceil(st.sigma_gate * sigma / step)), kb.size // 4) if step > 0.0 else 0

    def _near_tracks(self, scan: Scan, laser: Pose2D) -> np.ndarray:
        """Beams whose return lies on a live track with motion evidence (its radius plus the mask
        margin around where it is now), or on a confirmed person a leg of whom was seen this scan, walking or
        standing: a body that moves, or pauses in the candidate test for a cycle, must not write itself into
        the static map (its trail of occupied cells would hide its next steps' evidence), nor a person who
        stands (the cells its legs held would lie around its first step, and the free-space test asks for no
        occupied evidence around a point). A person standing still shows no free-space violation for it: the
        test at beam resolution (``seen_through``) finds its legs stopping the beams beside them."""
        tr = self._tracker
        live = [(float(t.state[0]), float(t.state[1]), t.radius_m) for t in tr.tracks
                if (tr.reported(t) or (not t.confirmed and t.evidence >= 1)) and tr.recently_seen(t)]
        if self._people is not None:
            live += [(float(t.filt.mean[0]), float(t.filt.mean[1]), self.config.people.person_radius_m)
                     for t in self._people.tracks if t.confirmed and t.legs]
        out = np.zeros(scan.ranges_m.size, bool)
        if not live:
            return out
        r = np.where(np.isfinite(scan.ranges_m), scan.ranges_m, np.inf)
        ang = laser.theta_rad + scan.bearings_rad
        x, y = laser.x_m + r * np.cos(ang), laser.y_m + r * np.sin(ang)
        for tx, ty, radius in live:
            reach = radius + self.config.track_mask_margin_m
            with np.errstate(invalid="ignore"):
                out |= np.hypot(x - tx, y - ty) <= reach
        return out

    def _laser_to_robot_points(self, ranges: np.ndarray, bearings: np.ndarray) -> np.ndarray:
        ok = np.isfinite(ranges) & (ranges >= self.config.psm.min_range_m)
        r, b = ranges[ok], bearings[ok]
        return scan_points(self.config.laser_mount, r, b)


def _nearest_within(r: np.ndarray, k: int) -> np.ndarray:
    """Per beam: the nearest return within ``k`` beams either side; NaN where the beam itself has none (no
    return there is no surface to stand in front of)."""
    if k <= 0:
        return r
    return _window_min(np.require(r, np.float64, ("C", "W")), k)


@njit(cache=True, nogil=True)
def _window_min(r, k):  # pragma: no cover - compiled
    """Per beam with a finite return: the smallest non-NaN value within ``k`` beams either side; NaN
    elsewhere."""
    out = np.full(r.size, np.nan)
    for i in range(r.size):
        if not math.isfinite(r[i]):
            continue
        lo = r[i]
        for j in range(max(i - k, 0), min(i + k + 1, r.size)):
            if r[j] < lo:  # NaN compares false
                lo = r[j]
        out[i] = lo
    return out


def _checked(scan: Scan) -> tuple[Scan, bool]:
    """Bearings must be finite and ascending; otherwise match nothing (the caller falls back)."""
    b = scan.bearings_rad
    ok = bool(b.size < 2 or (np.all(np.isfinite(b)) and np.all(np.diff(b) > 0)))
    if ok:
        return scan, True
    return Scan(np.full(b.size, np.nan), np.linspace(-1.0, 1.0, b.size), scan.stamp_s, scan.seq), False


def _with_evidence(legs: list[LegDetection], bodies: list[Body]) -> list[LegDetection]:
    """Each leg marked with the motion evidence of a body on any of its beams."""
    spans = [(b.scan_index_start, b.scan_index_stop) for b in bodies if b.evidence]
    return [replace(p, evidence=any(a < p.scan_index_stop and p.scan_index_start < z for a, z in spans))
            for p in legs]


def _beam_towards(scan: Scan, laser: Pose2D, x: float, y: float) -> tuple[float, float] | None:
    """(the range the scan returned on the beam towards world point (x, y) (NaN: none), the point's
    distance), or None outside the field of view."""
    b = scan.bearings_rad
    dx, dy = x - laser.x_m, y - laser.y_m
    bearing = wrap_angle(math.atan2(dy, dx) - laser.theta_rad)
    if b.size < 2 or not b[0] <= bearing <= b[-1]:
        return None
    k = int(np.clip(np.searchsorted(b, bearing), 0, b.size - 1))
    return float(scan.ranges_m[k]), math.hypot(dx, dy)


def _visibility(scan: Scan, laser: Pose2D, margin_m: float = 0.3):
    """``visible(x, y)``: the scan could have seen a body at that world point: inside the field of
    view, and the beam towards it returned no nearer than ``margin_m`` in front of it (or not at all:
    it went through)."""

    def visible(x: float, y: float) -> bool:
        beam = _beam_towards(scan, laser, x, y)
        return beam is not None and not (math.isfinite(beam[0]) and beam[0] < beam[1] - margin_m)

    return visible


def _returns_near(b: np.ndarray, ranges_m: np.ndarray, laser: Pose2D, radius_m: float):
    """``occupied(x, y)``: a return of the scan (``ranges_m`` on bearings ``b``; NaN: none, or removed) lies within
    ``radius_m`` of that world point: something stands there now, whether or not the leg detector took it."""

    def occupied(x: float, y: float) -> bool:
        dx, dy = x - laser.x_m, y - laser.y_m
        d = math.hypot(dx, dy)
        if b.size < 2 or d <= radius_m:
            return False
        bearing = wrap_angle(math.atan2(dy, dx) - laser.theta_rad)
        half = math.asin(radius_m / d)
        i0, i1 = np.searchsorted(b, bearing - half), np.searchsorted(b, bearing + half, side="right")
        if i1 <= i0:
            return False
        r, a = ranges_m[i0:i1], b[i0:i1] + laser.theta_rad
        with np.errstate(invalid="ignore"):
            near = np.hypot(laser.x_m + r * np.cos(a) - x, laser.y_m + r * np.sin(a) - y) <= radius_m
        return bool(np.any(near))

    return occupied


def _seen_through(scan: Scan, laser: Pose2D, margin_m: float = 0.15):
    """``seen_free(x, y)``: the beam towards that world point returned at least ``margin_m`` beyond it
    (a leg's width: nothing stands there now)."""

    def seen_free(x: float, y: float) -> bool:
        beam = _beam_towards(scan, laser, x, y)
        return beam is not None and math.isfinite(beam[0]) and beam[0] >= beam[1] + margin_m

    return seen_free


def _returned_before(grid: FreeSpaceGrid, laser: Pose2D, leg_radius_m: float):
    """``stood_before(x, y)``: something stood at the front of a leg centred at that world point (the point
    ``leg_radius_m`` nearer the laser, where a leg's returns lie) when the laser last saw that place before
    this scan (:meth:`FreeSpaceGrid.held`, asked before this scan is integrated)."""

    def stood_before(x: float, y: float) -> bool:
        return bool(grid.held(_leg_front(laser, x, y, leg_radius_m))[0])

    return stood_before


def _seen_before(memory: ScanMemory, laser: Pose2D, leg_radius_m: float, since_s: float):
    """``seen_before(x, y)``: a scan stamped at or after ``since_s`` (before this one,
    :meth:`ScanMemory.seen_through`) saw through the front of a leg centred at that world point
    (:func:`_leg_front`): the leg stands where nothing stood a moment ago. Only recent scans are asked, and a
    beam without an echo counts as passing beyond only where the laser looked from the same place
    (``same_view_echoless``): a place seen through from a far other viewpoint seconds before may hold a thing
    that returns no echo from there (a dark surface) or a surface met at grazing incidence."""

    def seen_before(x: float, y: float) -> bool:
        front = _leg_front(laser, x, y, leg_radius_m)
        return bool(memory.seen_through(front, since_s, same_view_echoless=True)[0])

    return seen_before


def _leg_front(laser: Pose2D, x: float, y: float, leg_radius_m: float) -> np.ndarray:
    """(1, 2): the front of a leg centred at the world point (x, y) as the laser sees it, ``leg_radius_m``
    nearer the laser, where the leg's returns lie."""
    dx, dy = x - laser.x_m, y - laser.y_m
    k = leg_radius_m / max(math.hypot(dx, dy), 1e-6)
    return np.array([[x - k * dx, y - k * dy]])


def _rest_flags(rest: Restoration, plain_psm: bool) -> EstimateFlag:
    flags = EstimateFlag.OBSTACLE_TOO_LARGE if rest.too_large else EstimateFlag.NONE
    if rest.bridge_invalid and not plain_psm:
        flags |= EstimateFlag.BRIDGE_INVALID
    return flags


def _held_before(grid: FreeSpaceGrid, laser: Pose2D, scan: Scan, bodies: list[Body]) -> list[bool]:
    """Per body: something stood at its nearest return when the laser last saw that place before this scan
    (:meth:`FreeSpaceGrid.held`, asked before this scan is integrated; tracked moving bodies write no
    occupancy, so it is the static background's or a body's that stood untracked). A body with no finite
    return: False."""
    if not bodies:
        return []
    r = np.where(np.isfinite(scan.ranges_m), scan.ranges_m, np.inf)
    spans = [(b.scan_index_start, b.scan_index_stop) for b in bodies]
    k = np.array([a + int(np.argmin(r[a:z])) if z > a else 0 for a, z in spans])
    ok = np.isfinite(r[k]) & np.array([z > a for a, z in spans])
    ang = laser.theta_rad + scan.bearings_rad[k]
    rk = np.where(ok, r[k], 0.0)
    xy = np.stack([laser.x_m + rk * np.cos(ang), laser.y_m + rk * np.sin(ang)], axis=1)
    return [bool(h) for h in grid.held(xy) & ok]


def _detection(b: Body, laser: Pose2D, heading_sigma_rad: float = math.nan, held: bool = False) -> Detection:
    """The tracker's detection of a body seen from ``laser`` (world frame) whose own heading error is
    ``heading_sigma_rad``; ``held``: something stood where it is when the laser last saw the place."""
    return Detection(b.x_m, b.y_m, b.radius_m, b.radius_fitted, b.scan_index_start, b.scan_index_stop,
                     b.bearing_min_rad, b.bearing_max_rad, evidence=b.evidence, sigma_m=_SIGMA_M[b.kind],
                     sigma_across_m=_SIGMA_ACROSS_M.get(b.kind), kind=b.kind,
                     occluded=b.occluded, behind_rad=_behind_rad(b, laser),
                     laser_x_m=laser.x_m, laser_y_m=laser.y_m, laser_theta_rad=laser.theta_rad,
                     heading_sigma_rad=heading_sigma_rad, held=held, legs_xy=b.legs_xy)


def _behind_rad(b: Body, laser: Pose2D) -> float:
    """The direction from the body's visible surface to its fitted centre (``Body.behind_rad``); a body built
    without one: the view line from the laser, a round body's seen whole."""
    return b.behind_rad if math.isfinite(b.behind_rad) else math.atan2(b.y_m - laser.y_m, b.x_m - laser.x_m)


def _obstacle(t: Track, det: Detection | None, laser: Pose2D, xy: tuple[float, float]) -> Obstacle:
    """The reported obstacle at ``xy`` (the track's position at the scan's stamp)."""
    if det is not None:
        bmin, bmax, i0, i1 = det.bearing_min_rad, det.bearing_max_rad, det.scan_index_start, det.scan_index_stop
    else:
        rel = between(laser, Pose2D(xy[0], xy[1], 0.0))
        d = max(math.hypot(rel.x_m, rel.y_m), 1e-6)
        b = math.atan2(rel.y_m, rel.x_m)
        half = math.asin(min(t.radius_m / d, 1.0))
        bmin, bmax, i0, i1 = b - half, b + half, -1, -1
    return Obstacle(
        track_id=t.track_id,
        x_m=float(xy[0]),
        y_m=float(xy[1]),
        vx_mps=float(t.state[2]),
        vy_mps=float(t.state[3]),
        radius_m=float(t.radius_m),
        bearing_min_rad=float(bmin),
        bearing_max_rad=float(bmax),
        scan_index_start=int(i0),
        scan_index_stop=int(i1),
        age_cycles=int(t.age_cycles),
        covariance=tuple(float(v) for v in np.asarray(t.cov, float).ravel()),
        person=bool(t.seen_as_person),
    )


def warm_up(config: EstimatorConfig | None = None) -> None:
    """Load every compiled kernel the estimator uses (compiling and caching them the first time on a
    machine) on made-up inputs of the types a live scan brings, so no cycle of a control loop pays for
    it: the scan matcher's, the static map's ray march, update, violation test and ring of occupied cells,
    the keyframe's nearest-return window, the assignment, the mixed-pixel island and ramp rules, the flow's
    global fit, the leg forest, the seen-through test, the body's circle refinement and the leg features
    (``tests/app/test_warm_up.py`` and the estimator's own warm-up test check that none is left)."""
    from .assignment import assign
    from .flow import warm_up as flow_warm_up
    from .legs import LegConfig, segment_features
    from .legs import warm_up as legs_warm_up
    from .psm import warm_up as psm_warm_up
    from .tracker import refine_fixed_radius

    cfg = config or EstimatorConfig()
    psm_warm_up(dataclasses.replace(cfg.psm, refine_iterations=max(cfg.psm.refine_iterations,
                                                                    cfg.no_odometry_refine_iterations)))
    b = np.linspace(-2.0, 2.0, 181)
    r = 3.0 + 0.5 * np.sin(3.0 * b)  # a made-up scan of a wavy room
    grid = FreeSpaceGrid(cfg.static_map)
    grid.integrate(0.0, (0.0, 0.0), 0.0, r, b)
    grid.violates(np.array([[1.0, 0.0]]))
    grid.occupied_cells_around(1.0, 0.0, 0.1, 0.5, 1.0)
    _nearest_within(r, 2)
    assign(np.array([[1.0, 2.0, 0.5], [0.3, 1.0, 2.0]]))
    veiling_masks(r, b, cfg.prefilter)  # the island and the ramp rules
    flow_warm_up(cfg.flow)
    legs_warm_up()
    memory = ScanMemory(cfg.seen_through)
    memory.push(Pose2D(0.0, 0.0, 0.0), r, b)
    memory.seen_through(np.array([[1.0, 0.0], [2.0, 0.5]]))
    refine_fixed_radius(np.array([[1.0, 0.0], [1.1, 0.1], [1.0, 0.2]]), 1.2, 0.1, 0.2)
    segment_features(r, b, [(10, 20)], LegConfig())
