"""The ROS 2 publisher beside the control loop: the loop hands it references (a few microseconds,
never a DDS call); its own thread builds the ROS 2 messages and writes them over DDS.

* Never blocks the loop: one bounded queue (``ros2.queue_size``); when it is full the oldest item
  is dropped for the newest and counted (``dropped``). Messages are built on the thread, from the
  loop's immutable samples and estimates, after the loop's cycle (:meth:`flush`): the thread's
  Python work then shares the GIL with the loop's idle time, not with its estimate.
* A DDS failure is a device-like state, never a crash: ``state`` goes ``starting`` -> ``ok``, or
  ``failed`` (no participant: bad config file, no usable network interface, ...), and a write that
  fails counts in ``errors`` (``last_error`` kept). Each state change and the first write error are
  events the loop says once on stderr and ``/log`` (:meth:`take_events`); the status registers'
  ``ros2_error`` bit and the run summary's ``ros2`` field carry the rest.
* Topics (under ``ros2.namespace``): ``/scan``, ``/odom``, ``/tf``, ``/tf_static``,
  ``/camera/image/compressed`` (with a camera), ``/vipsm/obstacles`` and ``/vipsm/people``
  (visualization_msgs/MarkerArray), ``/vipsm/obstacles/tracks`` and ``/vipsm/people/tracks``
  (radar_msgs/RadarTracks), ``/diagnostics`` (1 Hz). Nothing is queued before DDS is up (nobody can
  have subscribed yet), so the first messages are fresh.
"""

from __future__ import annotations

import os
import threading
import time
import typing
from collections import Counter, deque
from collections.abc import Callable
from pathlib import Path

from .. import logmessages as lm
from ..errors import ConfigError
from . import convert, qos

if typing.TYPE_CHECKING:
    from vipsm.types import Estimate, Odometry

    from ..config import Ros2Config
    from ..daemon import FrameSample, ScanSample

#: ROS 2 topic -> (ROS 2 type, QoS profile)
TOPICS: dict[str, tuple[str, qos.Profile]] = {
    "/scan": ("sensor_msgs/msg/LaserScan", qos.SENSOR_DATA),
    "/odom": ("nav_msgs/msg/Odometry", qos.DEFAULT),
    "/tf": ("tf2_msgs/msg/TFMessage", qos.TF),
    "/tf_static": ("tf2_msgs/msg/TFMessage", qos.TF_STATIC),
    "/camera/image/compressed": ("sensor_msgs/msg/CompressedImage", qos.DEFAULT),
    "/vipsm/obstacles": ("visualization_msgs/msg/MarkerArray", qos.DEFAULT),
    "/vipsm/people": ("visualization_msgs/msg/MarkerArray", qos.DEFAULT),
    "/vipsm/obstacles/tracks": ("radar_msgs/msg/RadarTracks", qos.DEFAULT),
    "/vipsm/people/tracks": ("radar_msgs/msg/RadarTracks", qos.DEFAULT),
    "/diagnostics": ("diagnostic_msgs/msg/DiagnosticArray", qos.DEFAULT),
}
DIAGNOSTICS_PERIOD_S = 1.0
#: the markers are for display (rviz2 draws at screen rate): at most 10 a second, where building and
#: serialising them in Python costs about 0.4 ms per obstacle shown; the tracks go out on every estimate
MARKER_PERIOD_S = 0.1
#: ROS 2's domain ids (the UDP port mapping leaves 0-232 usable)
MAX_DOMAIN_ID = 232


def resolve_domain_id(configured: int, environ: typing.Mapping[str, str] = os.environ) -> int:
    """``ros2.domain_id``, or ROS_DOMAIN_ID when it is -1 (unset: 0), as ROS 2 does."""
    if configured >= 0:
        return configured
    text = environ.get("ROS_DOMAIN_ID", "").strip()
    if not text:
        return 0
    if not text.isdigit() or int(text) > MAX_DOMAIN_ID:
        raise ConfigError("ROS_DOMAIN_ID", f"environment variable {text!r}: must be an integer 0-{MAX_DOMAIN_ID}")
    return int(text)


def cyclone_config_uri(path: str) -> str | None:
    """``ros2.cyclonedds_config`` as the URI Cyclone DDS reads (None: CYCLONEDDS_URI or its defaults);
    a file that is not there or not readable is a config error, before the loop starts."""
    if not path:
        return None
    p = Path(path).expanduser()
    try:
        with p.open("rb"):
            pass
    except OSError as exc:
        raise ConfigError("ros2.cyclonedds_config", f"cannot read {str(p)!r}: {exc.strerror or exc}") from exc
    return p.resolve().as_uri()


class Ros2Publisher:
    def __init__(self, config: Ros2Config, mounts: lm.Mounts, period_s: float, *,
                 wall_clock: Callable[[], float] = time.time) -> None:
        self.namespace = qos.normalise_namespace(config.namespace)
        self.domain_id = resolve_domain_id(config.domain_id)
        self.config_uri = cyclone_config_uri(config.cyclonedds_config)
        self.mounts = mounts
        self.lifetime_s = max(3 * period_s, 0.3)
        self.wall_clock = wall_clock
        self.run_id = os.urandom(8)
        self.state = "starting"
        self.error: str | None = None
        self.dropped = 0
        self.errors = 0
        self.last_error: str | None = None
        self.published: Counter[str] = Counter()
        self._queue: deque[tuple[str, Callable[[], typing.Any]]] = deque()
        self._queue_size = config.queue_size
        self._cond = threading.Condition()
        self._stop = False
        self._events: deque[tuple[str, str]] = deque(maxlen=32)
        self._thread = threading.Thread(target=self._run, name="ros2-publisher", daemon=True)
        self._writers: dict[str, typing.Any] = {}
        self._last_scan_stamp_s: float | None = None
        self._scan_time_s = 0.0
        self._pan_tilt = (0.0, 0.0)
        self._last_diag_s = -1e9
        self._last_markers_s = -1e9

    # -- the loop's side: references into the queue, nothing else ------------------------------

    def start(self) -> Ros2Publisher:
        self._thread.start()
        return self

    def _put(self, topic: str, build: Callable[[], typing.Any]) -> None:
        if self.state != "ok":  # before DDS is up nobody can have subscribed; after a failure nothing is sent
            return
        with self._cond:
            if len(self._queue) >= self._queue_size:
                self._queue.popleft()
                self.dropped += 1
            self._queue.append((topic, build))

    def flush(self) -> None:
        """Wakes the thread: the loop calls it once its cycle's work is done, so that building and
        serialising (Python, under the GIL) runs in the loop's idle time, not during its estimate
        (the thread also wakes by itself every 0.5 s)."""
        with self._cond:
            self._cond.notify()

    def scan(self, sample: ScanSample, wall_s: float) -> None:
        """One scan on ``/scan`` (REP 117 ranges when the driver gave them); scan_time is the interval
        since the previous scan (0 for the first)."""
        s = sample.scan
        if self._last_scan_stamp_s is not None and s.stamp_s > self._last_scan_stamp_s:
            self._scan_time_s = s.stamp_s - self._last_scan_stamp_s
        self._last_scan_stamp_s = s.stamp_s
        ranges = s.ranges_m if sample.rep117_ranges_m is None else sample.rep117_ranges_m
        limits, scan_time = sample.range_limits_m, self._scan_time_s
        self._put("/scan", lambda: convert.laser_scan(ranges, s.bearings_rad, s.beam_dt_s, wall_s, scan_time, limits))

    def frame(self, sample: FrameSample, wall_s: float) -> None:
        jpeg = sample.jpeg
        self._put("/camera/image/compressed", lambda: convert.compressed_image(jpeg, wall_s))

    def estimate(self, est: Estimate, odom: Odometry, wall_s: float, pan_tilt_rad: tuple[float, float] | None,
                 truth: dict[str, typing.Any] | None) -> None:
        """An estimate: ``/odom``, ``/tf``, the obstacles' and people's tracks, and their markers (at
        most every MARKER_PERIOD_S); ``wall_s`` is its scan's time on the wall clock."""
        if pan_tilt_rad is not None:
            self._pan_tilt = pan_tilt_rad
        pt, p, life = self._pan_tilt, est.pose, self.lifetime_s
        people = tuple(o for o in est.obstacles if o.person)
        self._put("/odom", lambda: convert.odometry(est, odom, wall_s))
        self._put("/tf", lambda: convert.dynamic_transforms((p.x_m, p.y_m, p.theta_rad), self.mounts, pt, wall_s,
                                                             truth))
        # a tenth of slack: a 10 Hz loop's jitter must not halve the markers' rate
        if wall_s - self._last_markers_s >= 0.9 * MARKER_PERIOD_S or wall_s < self._last_markers_s:
            self._last_markers_s = wall_s
            self._put("/vipsm/obstacles", lambda: convert.markers(est.obstacles, wall_s, life, "obstacles",
                                                                  convert.OBSTACLE_COLOR))
            self._put("/vipsm/people", lambda: convert.markers(people, wall_s, life, "people",
                                                               convert.PERSON_COLOR))
        self._put("/vipsm/obstacles/tracks", lambda: convert.tracks(est.obstacles, wall_s, self.run_id))
        self._put("/vipsm/people/tracks", lambda: convert.tracks(people, wall_s, self.run_id))

    def diagnostics(self, diag: dict[str, typing.Any], counters_fn: Callable[[], dict[str, dict[str, int]]],
                    wall_s: float) -> None:
        """``/diagnostics`` once a second (diagnostic_updater's rate), from the loop's health record and
        the devices' counters (``counters_fn`` is called on the loop's thread, only then)."""
        if wall_s - self._last_diag_s < DIAGNOSTICS_PERIOD_S:
            return
        self._last_diag_s = wall_s
        counters = counters_fn()
        self._put("/diagnostics", lambda: convert.diagnostics(diag, counters, self.summary(), wall_s))

    def take_events(self) -> list[tuple[str, str]]:
        """(level, message) of state changes since the last call, for the loop to say."""
        out = []
        while self._events:
            out.append(self._events.popleft())
        return out

    def summary(self) -> dict[str, typing.Any]:
        return {"state": self.state, "error": self.error, "domain_id": self.domain_id,
                "namespace": self.namespace or "/", "published": dict(self.published), "dropped": self.dropped,
                "errors": self.errors, "last_error": self.last_error}

    def close(self, timeout_s: float = 0.5) -> None:
        """Stops the thread (what is still queued is not sent; the thread deletes the DDS entities),
        waiting at most ``timeout_s``: the SIGTERM budget of the whole shutdown is 2 s."""
        with self._cond:
            self._stop = True
            self._cond.notify()
        if self._thread.is_alive():
            self._thread.join(timeout_s)

    # -- the publisher's thread ------------------------------------------------------------------

    def _run(self) -> None:
        try:
            participant = self._open()
        except Exception as exc:  # DDSException, an unusable config, no interface: a device-like failure
            self.error = f"{type(exc).__name__}: {exc}"
            self.state = "failed"
            self._events.append(("error", f"ros2: starting -> failed ({self.error}); the loop runs without it"))
            with self._cond:
                self._queue.clear()
            return
        self.state = "ok"
        ns = self.namespace or "/"
        self._events.append(("info", f"ros2: starting -> ok (domain {self.domain_id}, namespace {ns}, "
                                     f"{len(self._writers)} topics)"))
        try:
            self._write("/tf_static", lambda: convert.static_transforms(self.mounts, self.wall_clock()))
            self._serve()
        except Exception as exc:  # a bug here must still surface: the state says it, the loop says it once
            self.error = f"{type(exc).__name__}: {exc}"
            self.state = "failed"
            self._events.append(("error", f"ros2: ok -> failed ({self.error}); the loop runs without it"))
        finally:
            self._writers.clear()
            del participant  # deletes the topics and writers with it

    def _open(self) -> typing.Any:
        from cyclonedds.domain import Domain, DomainParticipant
        from cyclonedds.pub import DataWriter
        from cyclonedds.topic import Topic

        from .msgs import ROS_TYPES

        # a domain created with the file's configuration before the participant (else CYCLONEDDS_URI)
        self._domain = Domain(self.domain_id, self.config_uri) if self.config_uri else None
        participant = DomainParticipant(self.domain_id)
        for name, (ros_type, profile) in TOPICS.items():
            topic = Topic(participant, qos.dds_topic(self.namespace, name), ROS_TYPES[ros_type])
            self._writers[name] = DataWriter(participant, topic, qos=profile.dds_qos())
        return participant

    def _serve(self) -> None:
        while True:
            with self._cond:
                while not self._queue and not self._stop:
                    self._cond.wait(0.5)
                if self._stop:
                    return
                items = list(self._queue)
                self._queue.clear()
            for name, build in items:
                self._write(name, build)

    def _write(self, name: str, build: Callable[[], typing.Any]) -> None:
        try:
            self._writers[name].write(build())
            self.published[name] += 1
        except Exception as exc:  # a failed write (or a message that cannot be built) is counted, never raised
            self.errors += 1
            self.last_error = f"{name}: {type(exc).__name__}: {exc}"
            if self.errors == 1:
                self._events.append(("warning", f"ros2: write failed ({self.last_error}); further failures are "
                                                "counted in the summary's ros2.errors"))
