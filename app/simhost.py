"""The simulated robot's device side, run as a child process by ``vipsm-robot sim``.

``python -m app.simhost PARAMS_JSON DIR`` builds the world from scenario parameters and serves
the three byte-level fakes on it: the UTM-30LX and the Pioneer on pseudo-terminals (stable links
``DIR/scanner`` and ``DIR/robot``), the SNC-RZ50's VISCA on a pseudo-terminal (``DIR/camera``) and
its frames over loopback HTTP. The world's clock is ``time.monotonic() - T0`` (T0: when the
daemon says it is ready), shared by every fake, so the daemon's host stamps and the truth line up.

The world stands still at its time 0 until the daemon is ready: the fakes serve it from the start
(so the daemon's devices can open and stream), but no scenario time passes while the daemon compiles
its kernels and opens its devices, however long that takes on a slow or busy machine.

Protocol, one JSON object (or word) per line:

* on stdout, first ``{"scanner": path, "robot": path, "camera": path, "camera_http": url}`` (the world
  frozen at its time 0);
* on stdin, ``start`` when the daemon is ready for its first cycle: the world's clock starts (T0);
* on stdout, ``{"started": T0}`` in reply, then
  ``{"t": monotonic, "robot": [x, y, theta], "obstacles": [[x, y, vx, vy, r, moving, in_view], ...]}``
  every ``TRUTH_PERIOD_S`` (world frame; ``in_view``: moving and at least half inside the camera's
  horizontal field of view);
* last, after stdin closes (also before ``start``: the daemon gave up): ``{"final": {...}}`` with the
  fakes' byte counts and faults.
"""

from __future__ import annotations

import json
import math
import sys
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

from hil_fakes.pioneer import FakePioneer, PioneerConfig
from hil_fakes.snc_rz50 import CameraHttpServer, FakeCamera, serve_visca
from hil_fakes.transport import DeviceServer, PtyEndpoint
from hil_fakes.utm30lx import Utm30lxModel
from hil_fakes.world.scenarios import build_scenario
from hil_fakes.world.world import World

from .evaluation.metrics import obstacle_in_camera
from .evaluation.runner import tune_allocator

TRUTH_PERIOD_S = 0.02


class _Shift:
    """World adapters take world time; the fakes call with host monotonic time. Before ``start`` the
    world's time is 0 (T0 is +inf)."""

    def __init__(self) -> None:
        self.t0 = math.inf

    def start(self) -> float:
        self.t0 = time.monotonic()
        return self.t0

    def __call__(self, t_mono: float) -> float:
        return max(0.0, t_mono - self.t0)


class ShiftedRangeSource:
    def __init__(self, inner: Any, shift: _Shift) -> None:
        self.inner, self.shift = inner, shift

    def sweep(self, t0_s: float, angles_rad: np.ndarray, beam_dt_s: float) -> tuple[np.ndarray, np.ndarray]:
        return self.inner.sweep(self.shift(t0_s), angles_rad, beam_dt_s)  # type: ignore[no-any-return]


class ShiftedPlant:
    def __init__(self, inner: Any, shift: _Shift) -> None:
        self.inner, self.shift = inner, shift

    def command(self, v_mps: float, w_radps: float, now_s: float) -> None:
        self.inner.command(v_mps, w_radps, self.shift(now_s))

    def e_stop(self, now_s: float) -> None:
        self.inner.e_stop(self.shift(now_s))

    def state(self, now_s: float) -> tuple[float, float, float, float, float]:
        return self.inner.state(self.shift(now_s))  # type: ignore[no-any-return]


class ShiftedRenderer:
    def __init__(self, inner: Any, shift: _Shift) -> None:
        self.inner, self.shift = inner, shift
        self.width_px = inner.width_px
        self.height_px = inner.height_px

    def render(self, t_s: float, pan_rad: float, tilt_rad: float, hfov_rad: float) -> np.ndarray:
        return self.inner.render(self.shift(t_s), pan_rad, tilt_rad, hfov_rad)  # type: ignore[no-any-return]


class SimHost:
    def __init__(self, params: dict[str, Any], directory: Path) -> None:
        self.scenario = build_scenario(params)
        self.world = World(self.scenario)
        shift = _Shift()
        self.shift = shift
        w = self.world
        self.scanner_model = Utm30lxModel(source=ShiftedRangeSource(w.range_source(), shift))
        self.scanner = DeviceServer(self.scanner_model, PtyEndpoint(str(directory / "scanner"))).start()
        self._late_before_start = 0
        self.robot_model = FakePioneer(
            PioneerConfig(odometry_noise=self.scenario.odometry_noise),
            plant=ShiftedPlant(w.plant(), shift),
            sonar_world=w.sonar(),
        )
        self.robot = DeviceServer(self.robot_model, PtyEndpoint(str(directory / "robot"))).start()
        fx = self.scenario.camera_effects
        self.camera = FakeCamera(renderer=ShiftedRenderer(w.renderer(320, 240), shift),
                                 jpeg_quality=fx.jpeg_quality if fx.enabled else 80)
        power_pan_deg, power_zoom = self.scenario.camera_poweron
        self.camera.state.pan.move_to(0.0, -power_pan_deg * self.camera.spec.pan_counts_per_deg, 0.0)
        self.camera.state.zoom.move_to(0.0, float(power_zoom), 0.0)
        self.visca = serve_visca(self.camera, PtyEndpoint(str(directory / "camera")))
        self.http = CameraHttpServer(self.camera).start()

    def addresses(self) -> dict[str, Any]:
        return {
            "scanner": self.scanner.address,
            "robot": self.robot.address,
            "camera": self.visca.address,
            "camera_http": self.http.url,
        }

    def start(self) -> float:
        """The daemon is ready: the world's clock starts now; returns T0 (monotonic)."""
        self._late_before_start = self.scanner_model.scans_late  # the daemon's start-up starves the fakes
        return self.shift.start()

    def truth_line(self, t_mono: float) -> dict[str, Any]:
        tr = self.world.truth(self.shift(t_mono))
        mount = self.world.mount
        pan, _tilt, hfov = self.camera.state.view(t_mono)
        c, s = math.cos(tr.theta_rad), math.sin(tr.theta_rad)
        cam_x = tr.x_m + c * mount.camera_x_m - s * mount.camera_y_m
        cam_y = tr.y_m + s * mount.camera_x_m + c * mount.camera_y_m
        obs = [
            [
                o.x_m,
                o.y_m,
                o.vx_mps,
                o.vy_mps,
                o.radius_m,
                bool(o.moving),
                bool(o.moving and obstacle_in_camera(cam_x, cam_y, tr.theta_rad + pan, hfov, o.x_m, o.y_m, o.radius_m)),
            ]
            for o in tr.obstacles
        ]
        return {"t": t_mono, "robot": [tr.x_m, tr.y_m, tr.theta_rad], "obstacles": obs}

    def final(self) -> dict[str, Any]:
        out: dict[str, Any] = {}
        for name, srv in (("scanner", self.scanner), ("robot", self.robot), ("camera_visca", self.visca)):
            out[name] = {
                "bytes_in": srv.bytes_in,
                "bytes_out": srv.bytes_out,
                "bytes_dropped_no_client": srv.endpoint.dropped_no_client,
                "faults": vars(srv.faults.stats),
                "error": None if srv.error is None else repr(srv.error),
            }
        model = self.scanner_model
        # scans_late: while the world ran (its clock started), sent more than a scan period late or skipped
        late = model.scans_late - self._late_before_start
        out["scanner"].update({"scans_sent": model.frames_sent, "scans_late": late})
        out["camera_http"] = {"frames_sent": self.camera.frames_sent}
        return out

    def stop(self) -> None:
        self.http.stop()
        for srv in (self.scanner, self.robot, self.visca):
            try:
                srv.stop()
            except RuntimeError as exc:
                print(f"simhost: {exc}", file=sys.stderr)


def main(argv: list[str]) -> int:
    if len(argv) != 2:
        print("usage: python -m app.simhost PARAMS_JSON DIR", file=sys.stderr)
        return 2
    params = json.loads(argv[0])
    tune_allocator()  # rendered frames and sweeps are allocated every few ms
    host = SimHost(params, Path(argv[1]))
    out = sys.stdout
    out.write(json.dumps(host.addresses()) + "\n")
    out.flush()
    done = threading.Event()
    started = threading.Event()

    def watch_stdin() -> None:
        try:
            for line in sys.stdin:  # "start" once the daemon is ready; EOF when the parent closes it (or dies)
                if line.strip() == "start" and not started.is_set():
                    out.write(json.dumps({"started": host.start()}) + "\n")
                    out.flush()
                    started.set()
        except (OSError, ValueError) as exc:  # the parent went away mid-write
            print(f"simhost: {type(exc).__name__}: {exc}", file=sys.stderr)
        finally:
            done.set()
            started.set()

    threading.Thread(target=watch_stdin, daemon=True).start()
    try:
        started.wait()  # ends at "start" or when stdin closes (the parent closed it, or died)
        next_t = time.monotonic()
        while not done.is_set():
            now = time.monotonic()
            out.write(json.dumps(host.truth_line(now)) + "\n")
            out.flush()
            next_t += TRUTH_PERIOD_S
            done.wait(max(0.0, next_t - time.monotonic()))
    except BrokenPipeError:
        return 0
    finally:
        host.stop()
    try:
        out.write(json.dumps({"final": host.final()}) + "\n")
        out.flush()
    except BrokenPipeError:
        pass
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
