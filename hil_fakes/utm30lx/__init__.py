"""A byte-level fake Hokuyo UTM-30LX (SCIP 2.0, firmware P.1.05), written from the fact sheet.

This model does not import the driver: it is an independent reading of
``shared/protocols/scip2_utm30lx.md`` and of the real recorded session, so a codec bug cannot hide
behind the same bug in the fake.

What it does, as the recorded firmware P.1.05 did:

* VV/PP/II answer with the recorded text (II ``TIME`` is the fake's own 24-bit ms counter, in
  upper-case hex), BM answers ``02`` when the laser is already on, ``CR`` answers ``04``, an
  unknown command ``0E``; every reply is echo, status + sum, payload lines + sum, empty line.
* The mirror spins on the fake's own clock: one scan every 60/SCAN s (25 ms), starting at the
  moment the model first saw the clock; step 0 of scan k is latched at ``boot + k * period``.
  A scan is sent when its sweep over the step window is complete. Each timestamp is computed once
  from the scan's own start time and both its characters and its sum are built from that value.
* MD/ME: acknowledgement (echo, ``00P``, empty line), then one frame per scan (respecting the
  interval) whose echo carries the remaining count; ``count`` N stops after N frames (laser off),
  ``00`` streams until QT. GD/GE answer with the first scan that starts after the request; status ``10`` when the laser
  is off. TM0/TM1/TM2 with the SCIP statuses; in time-adjust mode every other command is refused
  (``0E``, as urg_library expects of a sensor stuck there).
* Ranges come from a pluggable :class:`RangeSource` (default :class:`FixedRoom`); NaN and values
  beyond DMAX become error code 1, values below DMIN error code 2.

Fault hooks beyond the transport's generic ones (:class:`hil_fakes.transport.FaultInjector`):
:meth:`Utm30lxModel.inject_status` (a command answered with an error status),
:meth:`Utm30lxModel.inject_frame_status` (stream frames replaced by an error status),
:meth:`Utm30lxModel.inject_checksum_error` (a wrong status, timestamp or data sum),
:meth:`Utm30lxModel.leave_streaming` (a previous client left MD running),
:meth:`Utm30lxModel.enter_time_mode` (a previous client left it in time-adjust mode),
:meth:`Utm30lxModel.power_cycle` (clock back to 0, laser off).

Unverified device behaviour is a config value with a stated default (see :class:`Utm30lxConfig`)."""

from __future__ import annotations

from .config import _MAX_CATCH_UP_SCANS, _SS_RATES, _TAG_CHARS, Utm30lxConfig, _PendingSingle, _Stream
from .model import Utm30lxModel
from .protocol import data_block, encode, info_line, scip_sum, status_line, time_line
from .server import serve_pty, serve_tcp
from .source import _MASK24, FixedRoom, RangeSource

__all__ = [
    "_MASK24",
    "RangeSource",
    "FixedRoom",
    "scip_sum",
    "encode",
    "data_block",
    "status_line",
    "info_line",
    "time_line",
    "Utm30lxConfig",
    "_Stream",
    "_PendingSingle",
    "_SS_RATES",
    "_TAG_CHARS",
    "_MAX_CATCH_UP_SCANS",
    "Utm30lxModel",
    "serve_pty",
    "serve_tcp",
]
