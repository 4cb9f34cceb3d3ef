"""What a real UTM-30LX does that an ideal ray caster does not: mixed pixels, dropouts, spurious returns.

Sources: the range noise is in :class:`~hil_fakes.world.sensors.LaserModel` (measured on a recorded
UTM-30LX frame, within the datasheet's +-30 mm over 0.1-10 m); Ye & Borenstein, "Characterization of a 2-D laser
scanner for mobile robot obstacle negotiation" (ICRA 2002) and Tang et al. / Kneip et al. on the
"mixed pixel" (veiling) effect of pulsed time-of-flight scanners; the UTM-30LX's error codes for
no echo (fact sheet, SCIP section on error values).

* **Footprint and mixed pixels.** The beam has a divergence (``divergence_rad``, 0.3 deg [?]: no
  datasheet figure; consistent with the recorded edges below); each beam is cast as ``footprint_rays``
  sub-rays across it. When they all hit one surface (their ranges within ``surface_gap_m``) the beam
  returns that surface. When the footprint straddles a depth edge, the UTM-30LX, a pulsed time-of-flight
  receiver, gets one echo per surface: a copy of its pulse (Gaussian, std ``echo_separation_m / 2`` in
  range) delayed by the surface's distance, as bright as its share of the footprint x reflectivity x the
  cosine of the incidence / distance squared (a Lambertian surface). It times the peak of their sum that
  belongs to the stronger echo (:func:`echo_peak`). Echoes much closer than ``echo_separation_m`` merge
  into one peak between the surfaces (a mixed pixel, nearer the brighter one); beyond it they stay two
  peaks and the stronger is reported, pulled towards the other by a few cm while the pulses still
  overlap; nothing ever lies between two surfaces far apart. ``echo_separation_m`` = 1.1 m [?] (a pulse of
  about 8.6 ns full width at half maximum; no datasheet gives it) is fitted to the recorded UTM-30LX:
  over the 678 depth edges of 25 scans (``psm_diosi_examples``, measured by ``tools/laser_edges.py`` with
  :mod:`.edges`) a mixed pixel lies at 0.69 / 0.76 / 0.06 of the edges 0.05-0.3 / 0.3-1 / > 1 m deep
  (0.83, 0.80, 0.69, 0.20, 0.02 at 0.15-0.3, 0.3-0.6, 0.6-1, 1-1.5, 1.5-2.5 m), and none has no echo;
  the world with 1.1 m gives 0.61 / 0.82 / 0.09 (0.81, 0.89, 0.73, 0.17, 0.01). (The recordings of
  people, another Hokuyo: 0.27 / 0.22 / 0.04, fitted by a 0.2 deg footprint on its 0.35 deg step and a
  0.8 m separation: ``LEG_TRACKER_*``.) Not modelled: the recorded UTM-30LX's pull of 3-6 cm towards the
  other surface at edges 1.5-3 m deep (0.36-0.44 of them; the world's Gaussian pulse: 0.10-0.14), a
  longer tail than a Gaussian's. A footprint partly on nothing returns the foreground with probability
  ``f``, its share of the footprint, else no echo.
* **Grazing incidence.** Beyond ``grazing_limit_deg`` from the surface normal too little light comes
  back: no return (at a depth edge: judged on the sub-ray that returns most of the reported echo's light).
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
    #: two echoes this far apart in range are resolved as two (the pulse's std is half of it)
    echo_separation_m: float = 1.1
    grazing_limit_deg: float = 78.0
    dropout_prob: float = 0.001
    spurious_prob: float = 2e-4
    #: the range noise (:class:`~hil_fakes.world.sensors.LaserModel`) times this: 1 the measured sensor,
    #: about 3 the datasheet's accuracy bound read as 3 sigma of random noise (a pessimistic world)
    noise_scale: float = 1.0

    def __post_init__(self) -> None:
        if self.footprint_rays < 1 or self.footprint_rays % 2 == 0:
            raise ValueError("footprint_rays must be odd and >= 1 (one ray on the beam's axis)")
        if not (math.isfinite(self.echo_separation_m) and 0.0 <= self.echo_separation_m <= 10.0):
            raise ValueError(f"LaserEffects.echo_separation_m must be in [0, 10] m, got {self.echo_separation_m}")
        for name in ("dropout_prob", "spurious_prob"):
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
#: the other sensor class: the 768-beam Hokuyo of the people recordings (0.3516 deg steps), fitted the same
#: way on its 21814 edges of ``negative_2`` (``tools/laser_edges.py --fine``: mixed 0.24 / 0.32 / 0.24 / 0.15
#: / 0.04 at gaps 0.05-0.15 / 0.15-0.3 / 0.3-0.6 / 0.6-1 / 1-1.5 m, against the world's 0.15 (its thin
#: furniture) / 0.28 / 0.30 / 0.16 / 0.03 with these): a footprint narrower than its step, a shorter pulse
LEG_TRACKER_DIVERGENCE_DEG = 0.2
LEG_TRACKER_ECHO_SEPARATION_M = 0.8
#: the search for the waveform's peak stops when no beam's estimate moves more than this (m), or after
#: this many mean-shift steps (where two echoes are about one separation apart the peak is flat and the
#: steps shrink slowly)
ECHO_PEAK_TOL_M = 1e-4
ECHO_PEAK_MAX_STEPS = 200


def footprint_return(
    dist_m: np.ndarray, cos_inc: np.ndarray, surface: np.ndarray, fx: LaserEffects, rng: np.random.Generator,
    refl: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Combine the sub-rays of each beam into one range.

    ``dist_m`` (N, S): distance of each sub-ray (inf: nothing hit); ``cos_inc`` (N, S): cosine of the
    incidence angle there; ``surface`` (N, S): which surface each sub-ray hit (a footprint spread over
    one surface, as at grazing incidence, is no depth edge); ``refl`` (N, S): the surface's reflectivity
    (None: all alike). Returns (range_m (N,) before noise, NaN = no echo; the sub-ray index whose surface
    the beam reports, -1 for a mixed or missing echo)."""
    n, s = dist_m.shape
    centre = s // 2
    finite = np.isfinite(dist_m)
    near = np.min(np.where(finite, dist_m, np.inf), axis=1)
    fg = finite & (dist_m <= near[:, None] + fx.surface_gap_m)
    frac = fg.sum(axis=1) / s
    far = np.max(np.where(finite & ~fg, dist_m, -np.inf), axis=1)
    has_bg = np.isfinite(far)
    r_fg = np.where(fg, dist_m, 0.0).sum(axis=1) / np.maximum(fg.sum(axis=1), 1)
    u = rng.random((n, 3))  # u[:, 0] drew the old mixing coin; kept so that the other draws stay the same
    out = np.where(finite[:, centre], dist_m[:, centre], np.nan)
    src = np.where(finite[:, centre], centre, -1)
    one_surface = finite.all(axis=1) & (surface == surface[:, centre : centre + 1]).all(axis=1)
    edge = (frac < 1.0) & (frac > 0.0) & ~one_surface
    # straddling two surfaces: the receiver's waveform holds both echoes
    two = np.flatnonzero(edge & has_bg)
    lit = np.full(n, -1)
    if two.size:
        r_two, src_two, lit[two] = echo_peak(dist_m[two], cos_inc[two], fg[two], fx,
                                              None if refl is None else refl[two])
        out[two], src[two] = r_two, src_two
    first_fg = np.argmax(fg, axis=1)
    # partly on nothing
    part = edge & ~has_bg
    keep = part & (u[:, 1] < frac)
    out = np.where(part, np.where(keep, r_fg, np.nan), out)
    src = np.where(part, np.where(keep, first_fg, -1), src)
    # grazing incidence on the reported surface (two surfaces: the sub-ray that returns most of the
    # stronger echo's light; else the reported sub-ray, or the beam's axis)
    look = np.where(lit >= 0, lit, np.where(src >= 0, src, centre))
    cos_src = np.take_along_axis(cos_inc, look[:, None], axis=1)[:, 0]
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


def echo_peak(
    dist_m: np.ndarray, cos_inc: np.ndarray, fg: np.ndarray, fx: LaserEffects, refl: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The range a pulsed receiver reports for footprints (M, S) that straddle a depth edge.

    Each sub-ray returns a copy of the emitted pulse (Gaussian, std ``echo_separation_m / 2`` in range)
    delayed by its distance, with the energy of a Lambertian surface (reflectivity x cosine of the
    incidence / distance squared); the receiver times the peak of their sum that belongs to the stronger
    echo (found by mean shift from the stronger of the foreground ``fg`` and the background group). Echoes
    much closer than the separation merge into one peak between them (a mixed pixel, weighted by their
    energies); farther apart they stay two peaks and the stronger is reported, pulled towards the other by
    its pulse's tail. Returns (range_m (M,); the sub-ray index whose surface is reported, -1 for a peak
    more than ``surface_gap_m`` from both surfaces; the sub-ray that returns most of the stronger echo's
    light, whose incidence decides whether the echo is too weak: grazing)."""
    finite = np.isfinite(dist_m)
    d = np.where(finite, dist_m, 0.0)
    e = np.where(finite, np.clip(cos_inc, 0.0, 1.0) / np.maximum(d, 0.1) ** 2, 0.0)
    if refl is not None:
        e = e * np.where(finite, refl, 0.0)
    bg = finite & ~fg
    e_fg, e_bg = np.where(fg, e, 0.0).sum(axis=1), np.where(bg, e, 0.0).sum(axis=1)
    strong = np.where((e_fg >= e_bg)[:, None], fg, bg)
    w0 = np.where(strong, np.maximum(e, 1e-12), 0.0)
    r = (w0 * d).sum(axis=1) / w0.sum(axis=1)
    sigma = fx.echo_separation_m / 2.0
    if sigma > 0.0:
        for _ in range(ECHO_PEAK_MAX_STEPS):
            k = e * np.exp(-0.5 * ((d - r[:, None]) / sigma) ** 2)
            tot = k.sum(axis=1)
            new = np.where(tot > 0.0, (k * d).sum(axis=1) / np.maximum(tot, 1e-300), r)
            moved = float(np.max(np.abs(new - r)))
            r = new
            if moved < ECHO_PEAK_TOL_M:
                break
    on_strong = np.where(strong, np.abs(d - r[:, None]), np.inf)
    first = np.argmin(on_strong, axis=1)
    src = np.where(np.min(on_strong, axis=1) <= fx.surface_gap_m, first, -1)
    return r, src, np.argmax(np.where(strong, e, -1.0), axis=1)
