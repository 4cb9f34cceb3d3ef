"""The camera frame for a scan: the one taken nearest the scan's stamp, not the newest one received.

The scanner's stream and the camera's reach the loop with different, varying delays (USB against
HTTP, a reader thread waiting for a busy interpreter). A scan received 0.4 s after its sweep paired
with the newest frame pairs two views of the world 0.4 s apart; the estimator then refuses the frame
(``STALE_FRAME``) and runs without the camera, cycle after cycle, for as long as the delay lasts. The
loop therefore keeps the last few frames and pairs each scan with the frame whose stamp is nearest
the scan's, as a ROS approximate-time synchroniser does.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

from vipsm.types import Frame


@dataclass(frozen=True)
class FrameSample:
    """A decoded camera frame as the loop received it, with its JPEG (for the log) and the zoom it was
    taken at (``app.daemon`` re-exports it: the camera port's type)."""

    frame: Frame
    jpeg: bytes
    zoom_pos: int = 0

#: frames kept: 1.6 s at the SNC-RZ50's 10 frames a second over HTTP, 0.5 s at 30. A scan later than
#: that is stale to the scanner's own stall age long before its frame would be dropped here.
RECENT_FRAMES = 16


class RecentFrames:
    """The last :data:`RECENT_FRAMES` frame samples (bounded), and the one to pair with a scan."""

    def __init__(self, keep: int = RECENT_FRAMES) -> None:
        if keep < 1:
            raise ValueError(f"keep must be at least 1, got {keep}")
        self._samples: deque[FrameSample] = deque(maxlen=keep)
        self._used_stamp_s = float("-inf")

    def add(self, sample: FrameSample) -> None:
        """A frame received; frames arrive in stamp order (one camera), an older stamp restarts the ring
        (the camera's clock or stream was reset)."""
        if self._samples and sample.frame.stamp_s < self._samples[-1].frame.stamp_s:
            self._samples.clear()
            self._used_stamp_s = float("-inf")
        self._samples.append(sample)

    def __len__(self) -> int:
        return len(self._samples)

    @property
    def newest(self) -> FrameSample | None:
        """The frame received last (None: none yet)."""
        return self._samples[-1] if self._samples else None

    def nearest(self, stamp_s: float, max_gap_s: float) -> FrameSample | None:
        """The frame taken nearest ``stamp_s``, at most ``max_gap_s`` from it, and never older than the
        frame this returned last (the estimator's optical flow runs forward in time); None if none."""
        best: FrameSample | None = None
        best_gap_s = max_gap_s
        for s in self._samples:
            t = s.frame.stamp_s
            if t < self._used_stamp_s:
                continue
            gap_s = abs(t - stamp_s)
            if gap_s <= best_gap_s:
                best, best_gap_s = s, gap_s
        if best is not None:
            self._used_stamp_s = best.frame.stamp_s
        return best
