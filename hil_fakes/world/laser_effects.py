"""What a real UTM-30LX does that an ideal ray caster does not: mixed pixels, dropouts, spurious returns.

Sources: the range noise is in :class:`~hil_fakes.world.sensors.LaserModel` (measured on a recorded
UTM-30LX frame, within the datasheet's +-30 mm over 0.1-10 m); Ye & Borenstein, "Characterization of a 2-D laser
scanner for mobile robot obstacle negotiation" (ICRA 2002) and Tang et al. / Kneip et al. on the
"mixed pixel" (veiling) effect of pulsed time-of-flight scanners; the UTM-30LX's error codes for
no echo (fact sheet, SCIP section on error values).

* **Footprint and mixed pixels.** The beam has a divergence (``divergence_rad``, 0.25-0.4 deg for
  this class of scanner [?]); each beam is cast as ``footprint_rays`` sub-rays across it. When they
  all hit one surface (their ranges within ``surface_gap_m``) the beam returns that surface. When the
  footprint straddles a depth edge, the echoes of the foreground (a fraction ``f`` of the footprint)
  and the background merge in the receiver: with probability ``mixed_prob`` the range is the
  energy-weighted mixture ``f * r_fg + (1 - f) * r_bg`` (a point floating between the surfaces, only
  ever at depth edges); otherwise the dominant echo wins (the foreground when ``f >= 0.5``). A
  footprint partly on nothing returns the foreground with probability ``f``, else no echo.
* **Grazing incidence.** Beyond ``grazing_limit_deg`` from the surface normal too little light comes
  back: no return.
* **Random dropouts** (``dropout_prob`` per beam) and **spurious short returns**
  (``spurious_prob`` per beam: dust, a reflection; uniform between the minimum range and the true one).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class LaserEffects:
    enabled: bool = True
    divergence_rad: float = math.radians(0.3)
    footprint_rays: int = 5
    surface_gap_m: float = 0.05
    mixed_prob: float = 0.5
    grazing_limit_deg: float = 78.0
    dropout_prob: float = 0.001
    spurious_prob: float = 2e-4
    #: the range noise (:class:`~hil_fakes.world.sensors.LaserModel`) times this: 1 the measured sensor,
    #: about 3 the datasheet's accuracy bound read as 3 sigma of random noise (a pessimistic world)
    noise_scale: float = 1.0

    def __post_init__(self) -> None:
        if self.footprint_rays < 1 or self.footprint_rays % 2 == 0:
            raise ValueError("footprint_rays must be odd and >= 1 (one ray on the beam's axis)")
        for name in ("mixed_prob", "dropout_prob", "spurious_prob"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise ValueError(f"LaserEffects.{name} must be a probability")
        if not (math.isfinite(self.noise_scale) and self.noise_scale >= 0.0):
            raise ValueError(f"LaserEffects.noise_scale must be >= 0, got {self.noise_scale}")

    def offsets_rad(self) -> np.ndarray:
        """Angular offsets of the sub-rays from the beam's axis (one ray only when disabled)."""
        if not self.enabled or self.footprint_rays == 1:
            return np.zeros(1)
        return np.linspace(-self.divergence_rad / 2, self.divergence_rad / 2, self.footprint_rays)


IDEAL_LASER = LaserEffects(enabled=False)


def footprint_return(
    dist_m: np.ndarray, cos_inc: np.ndarray, surface: np.ndarray, fx: LaserEffects, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """Combine the sub-rays of each beam into one range.

    ``dist_m`` (N, S): distance of each sub-ray (inf: nothing hit); ``cos_inc`` (N, S): cosine of the
    incidence angle there; ``surface`` (N, S): which surface each sub-ray hit (a footprint spread over
    one surface, as at grazing incidence, is no depth edge). Returns (range_m (N,) before noise, NaN =
    no echo; the sub-ray index whose surface the beam reports, -1 for a mixed or missing echo)."""
    n, s = dist_m.shape
    centre = s // 2
    finite = np.isfinite(dist_m)
    near = np.min(np.where(finite, dist_m, np.inf), axis=1)
    fg = finite & (dist_m <= near[:, None] + fx.surface_gap_m)
    frac = fg.sum(axis=1) / s
    far = np.max(np.where(finite & ~fg, dist_m, -np.inf), axis=1)
    has_bg = np.isfinite(far)
    bg = finite & ~fg
    r_fg = np.where(fg, dist_m, 0.0).sum(axis=1) / np.maximum(fg.sum(axis=1), 1)
    r_bg = np.where(bg, dist_m, 0.0).sum(axis=1) / np.maximum(bg.sum(axis=1), 1)
    u = rng.random((n, 3))
    out = np.where(finite[:, centre], dist_m[:, centre], np.nan)
    src = np.where(finite[:, centre], centre, -1)
    one_surface = finite.all(axis=1) & (surface == surface[:, centre : centre + 1]).all(axis=1)
    edge = (frac < 1.0) & (frac > 0.0) & ~one_surface
    # straddling two surfaces
    two = edge & has_bg
    mixed = two & (u[:, 0] < fx.mixed_prob)
    out = np.where(mixed, frac * r_fg + (1.0 - frac) * r_bg, out)
    src = np.where(mixed, -1, src)
    dom = two & ~mixed
    first_fg = np.argmax(fg, axis=1)
    first_bg = np.argmax(bg, axis=1)
    out = np.where(dom & (frac >= 0.5), r_fg, np.where(dom, r_bg, out))
    src = np.where(dom & (frac >= 0.5), first_fg, np.where(dom, first_bg, src))
    # partly on nothing
    part = edge & ~has_bg
    keep = part & (u[:, 1] < frac)
    out = np.where(part, np.where(keep, r_fg, np.nan), out)
    src = np.where(part, np.where(keep, first_fg, -1), src)
    # grazing incidence on the reported surface (a mixed echo: on the beam's axis)
    cos_src = np.take_along_axis(cos_inc, np.where(src >= 0, src, centre)[:, None], axis=1)[:, 0]
    grazing = np.isfinite(out) & (cos_src < math.cos(math.radians(fx.grazing_limit_deg)))
    out = np.where(grazing, np.nan, out)
    # random dropouts and spurious short returns
    out = np.where(u[:, 2] < fx.dropout_prob, np.nan, out)
    spurious = (u[:, 2] >= fx.dropout_prob) & (u[:, 2] < fx.dropout_prob + fx.spurious_prob)
    upper = np.where(np.isfinite(out), out, 30.0)
    fake = 0.05 + rng.random(n) * np.maximum(upper - 0.05, 0.0)
    out = np.where(spurious, fake, out)
    src = np.where(spurious | grazing, -1, src)
    return out, src
