"""What a real SNC-RZ50 frame has that a pinhole render does not.

* **Lens**: radial distortion (Brown-Conrady ``k1``, ``k2``; a wide-angle zoom lens at its wide end
  is barrel-distorted, k1 about -0.1 to -0.2 [?]), the principal point a few pixels off the image
  centre (``pp_offset_px``), and the camera mounted with a small yaw error (``mount_yaw_rad``).
  The image is rendered through a pinhole with the true principal point on a larger canvas and
  resampled through OpenCV's distortion model, so a world point lands exactly where
  ``cv2.projectPoints`` with these parameters puts it.
* **Timing**: the camera runs on its own crystal (``fps`` with ``clock_ppm`` rate error and a random
  phase), not synchronised with the laser; each frame reaches the host ``latency_s`` (40-100 ms:
  exposure, JPEG encoding, the network) after its exposure, with jitter.
* **Photometry**: exposure drift of a few percent (auto-exposure hunting), vignetting
  (``vignetting``: relative fall-off in the corners, cos^4-like), motion blur over the exposure time
  (``exposure_s``; the scene is rendered at the start and the end of the exposure and averaged), and
  JPEG compression at ``jpeg_quality`` (50-75 on the RZ50's web settings).
* **Lights switched off or on** (``lights``: the room's light level against time, 1 = on): the scene's
  radiance drops at once by the level; the camera's auto-exposure then raises its gain in steps of
  ``ae_step_db`` every ``ae_period_s`` until the image is as bright as before (each step an exposure
  jump), and the sensor's noise, referred to the image, rises with the gain: lights at 1/3 give the
  same brightness with 3x the gain and 3x the noise. Switching back on is the same in reverse.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import cv2
import numpy as np


@dataclass(frozen=True)
class CameraEffects:
    enabled: bool = True
    k1: float = -0.15
    k2: float = 0.02
    pp_offset_px: tuple[float, float] = (3.0, -2.0)
    mount_yaw_rad: float = math.radians(0.4)
    fps: float = 25.0
    clock_ppm: float = 60.0
    latency_s: tuple[float, float] = (0.04, 0.10)
    exposure_s: float = 1.0 / 60.0
    exposure_drift: float = 0.03
    vignetting: float = 0.25
    jpeg_quality: int = 65
    #: the room's light level from each instant on: (t_s, level) steps, 1 = lights on; () = always on
    lights: tuple[tuple[float, float], ...] = ()
    #: auto-exposure gain step and the interval between steps [?] (camcorder-class AE: 1-3 dB steps,
    #: several per second; the SNC-RZ50's own are not published)
    ae_step_db: float = 2.0
    ae_period_s: float = 0.2

    def __post_init__(self) -> None:
        lo, hi = self.latency_s
        if not (0.0 <= lo <= hi <= 1.0):
            raise ValueError(f"CameraEffects.latency_s must be 0 <= lo <= hi <= 1 s, got {self.latency_s}")
        if not (1.0 <= self.fps <= 60.0 and 1 <= self.jpeg_quality <= 100 and 0.0 <= self.exposure_s < 0.2):
            raise ValueError(f"implausible camera effects {self}")
        if any(not 0.01 <= level <= 1.0 for _, level in self.lights) or self.ae_step_db <= 0 or self.ae_period_s <= 0:
            raise ValueError(f"CameraEffects: light levels must be 0.01..1 and the AE step and period > 0, got {self}")


IDEAL_CAMERA = CameraEffects(enabled=False)


@lru_cache(maxsize=8)
def distortion_maps(
    width_px: int, height_px: int, fx: float, fy: float, cx: float, cy: float, k1: float, k2: float, margin_px: int
) -> tuple[np.ndarray, np.ndarray]:
    """cv2.remap maps from the distorted output image into a pinhole canvas ``margin_px`` larger on
    every side, whose principal point is (cx + margin, cy + margin)."""
    u, v = np.meshgrid(np.arange(width_px, dtype=np.float64), np.arange(height_px, dtype=np.float64))
    pts = np.stack([u.ravel(), v.ravel()], axis=-1).reshape(-1, 1, 2)
    k = np.array([[fx, 0, cx], [0, fy, cy], [0, 0, 1]], dtype=np.float64)
    dist = np.array([k1, k2, 0.0, 0.0, 0.0])
    und = cv2.undistortPoints(pts, k, dist, P=k).reshape(height_px, width_px, 2)
    map_x = (und[..., 0] + margin_px).astype(np.float32)
    map_y = (und[..., 1] + margin_px).astype(np.float32)
    return map_x, map_y


@lru_cache(maxsize=8)
def vignette_gain(width_px: int, height_px: int, strength: float) -> np.ndarray:
    u, v = np.meshgrid(np.linspace(-1, 1, width_px), np.linspace(-1, 1, height_px))
    r2 = (u * u + v * v) / 2.0  # 1 in the corners
    return (1.0 - strength * r2).astype(np.float32)[..., None]


def photometric(img: np.ndarray, gain: float, fx: CameraEffects) -> np.ndarray:
    g = vignette_gain(img.shape[1], img.shape[0], fx.vignetting) * np.float32(gain)
    return np.clip(img.astype(np.float32) * g, 0, 255).astype(np.uint8)


def light_and_gain(t_s: float, fx: CameraEffects) -> tuple[float, float]:
    """(light level, auto-exposure gain) at ``t_s``: after each change of the light level the gain steps
    by ``ae_step_db`` every ``ae_period_s`` towards 1 / level (the brightness it had with the lights on)."""
    level, gain_db = 1.0, 0.0
    events = sorted(fx.lights)
    for k, (t_ev, new_level) in enumerate(events):
        if t_ev > t_s:
            break
        level = new_level
        target_db = -20.0 * math.log10(level)
        t_next = events[k + 1][0] if k + 1 < len(events) else math.inf
        steps = math.floor((min(t_s, t_next) - t_ev) / fx.ae_period_s + 1e-9)
        change = max(-steps * fx.ae_step_db, min(steps * fx.ae_step_db, target_db - gain_db))
        gain_db += change
    return level, 10.0 ** (gain_db / 20.0)


def jpeg_roundtrip(img: np.ndarray, quality: int) -> np.ndarray:
    ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
    if not ok:
        raise RuntimeError("OpenCV could not encode a JPEG frame")
    return cv2.imdecode(buf, cv2.IMREAD_COLOR)


@dataclass(frozen=True)
class FrameTiming:
    seq: int
    capture_s: float
    delivery_s: float


class CameraClock:
    """The camera's free-running frame clock and the delivery latency of each frame (deterministic
    per frame number, so asking twice gives the same answer)."""

    def __init__(self, fx: CameraEffects, seed: int) -> None:
        self.fx = fx
        rng = np.random.default_rng([seed, 7])
        self.period_s = (1.0 + fx.clock_ppm * 1e-6) / fx.fps
        self.phase_s = float(rng.uniform(0.0, self.period_s))
        self._seed = seed

    def capture_s(self, seq: int) -> float:
        return self.phase_s + seq * self.period_s

    def latency_s(self, seq: int) -> float:
        lo, hi = self.fx.latency_s
        return lo + (hi - lo) * float(np.random.default_rng([self._seed, 8, seq]).random())

    def exposure_gain(self, t_s: float) -> float:
        """Auto-exposure hunting: a slow oscillation of +- ``exposure_drift``."""
        return 1.0 + self.fx.exposure_drift * math.sin(2 * math.pi * t_s / 7.3 + self.phase_s * 10.0)

    def newest(self, t_s: float) -> FrameTiming | None:
        """The newest frame delivered at or before ``t_s`` (None before the first)."""
        n = math.floor((t_s - self.phase_s) / self.period_s)
        hi = self.fx.latency_s[1]
        for seq in range(n, max(-1, n - int(hi / self.period_s) - 3), -1):
            if seq < 0:
                break
            cap = self.capture_s(seq)
            dl = cap + self.latency_s(seq)
            if dl <= t_s:
                return FrameTiming(seq, cap, dl)
        return None
