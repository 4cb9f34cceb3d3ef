"""A byte-level fake Pioneer 3-DX running ARCOS, written from the fact sheet (protocols/arcos_p3dx.md).

It is an independent model of the controller: it has its own framing, checksum and command parser
and never imports the driver, so a codec bug cannot hide behind the same bug here.

What it models:

* the handshake SYNC0/SYNC1/SYNC2 (reply: name, class, subclass), restarting at SYNC0 when a SYNC
  comes out of order (as real ARCOS does, fact sheet 1.4); OPEN starts a SIP every ``sip_cycle_s``;
  CLOSE ends the session; OPEN/CLOSE with an argument are accepted;
* CONFIG (CONFIGpac 0x20 in ARIA's field order), ENCODER (0x90 stream), IOREQUEST (0xF0), the velocity commands
  (VEL, RVEL, ROTATE, VEL2, STOP, E_STOP), limits (SETV, SETA, SETRV, SETRA), ENABLE (motors start
  disabled unless configured otherwise), SETO, SONAR, HOSTBAUD, RESET; other known commands are
  accepted and counted; frames with a bad checksum are ignored and counted;
* motion through a :class:`Plant` (default: :class:`hil_fakes.kinematics.Unicycle` advanced on the
  fake's clock), odometry through :class:`hil_fakes.wheel_odometry.WheelOdometry` in the
  controller's raw frame (optionally starting at a raw offset, so the 15-bit X/Y and the 12-bit
  heading wrap in tests) sent as wrapping 16-bit counters (only the low 15 bits are valid);
* 16 sonars at the p3dx.p poses, ray-cast in a :class:`SonarWorld` (default: a rectangular room);
* the firmware watchdog: motion halts after ``watchdog_s`` without a command; when commands
  return, the old setpoint resumes or not (``watchdog_resume``, unverified on hardware);
* faults on top of the transport's: a reset packet, a stale open session, out-of-order SYNC
  replies, junk before SIPs.

``truth(now_s)`` gives the plant's ground truth and ``raw_odometry_pose()`` the controller's own
odometry (equal to the truth, moved to the raw frame, when the odometry noise is zero)."""

from __future__ import annotations

from .cli import _ARCOS_RATES, add_arguments, config_from_args, pty_line_baud, run_from_args, serve
from .model import _BAUDS, FakePioneer, PioneerConfig, PioneerStats
from .plant import _ANGLE_UNIT_RAD, SONAR_POSES_MM_DEG, Plant, RectangularRoom, SonarWorld, UnicyclePlant
from .protocol import (
    _KNOWN_OTHERS,
    BATTERYINFO,
    CLOSE,
    CONFIG,
    DIST_CONV_MM,
    E_STOP,
    ENABLE,
    ENCODER,
    HOSTBAUD,
    IOREQUEST,
    OPEN,
    PULSE,
    RESET,
    ROTATE,
    RVEL,
    SETA,
    SETO,
    SETRA,
    SETRV,
    SETV,
    SONAR,
    STOP,
    SYNC0,
    SYNC1,
    SYNC2,
    VEL,
    VEL2,
    _arg,
    _HostFrames,
    arcos_checksum,
    arcos_packet,
)

__all__ = [
    "Plant",
    "SonarWorld",
    "UnicyclePlant",
    "RectangularRoom",
    "_ANGLE_UNIT_RAD",
    "SONAR_POSES_MM_DEG",
    "DIST_CONV_MM",
    "arcos_checksum",
    "arcos_packet",
    "_HostFrames",
    "_arg",
    "SYNC0",
    "SYNC1",
    "SYNC2",
    "PULSE",
    "OPEN",
    "CLOSE",
    "ENABLE",
    "SETA",
    "SETV",
    "SETO",
    "ROTATE",
    "SETRV",
    "VEL",
    "CONFIG",
    "ENCODER",
    "RVEL",
    "SETRA",
    "SONAR",
    "STOP",
    "VEL2",
    "HOSTBAUD",
    "E_STOP",
    "BATTERYINFO",
    "RESET",
    "IOREQUEST",
    "_KNOWN_OTHERS",
    "_BAUDS",
    "PioneerConfig",
    "PioneerStats",
    "FakePioneer",
    "serve",
    "_ARCOS_RATES",
    "pty_line_baud",
    "add_arguments",
    "config_from_args",
    "run_from_args",
]
