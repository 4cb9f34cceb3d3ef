"""Pioneer 3-DX over ARCOS (P2OS): sans-I/O codec, wrap-safe odometry and a threaded client.

See docs/robot.md. ``codec`` and ``odometry`` are pure (no port, clock or thread); ``client``
owns the port and the reader thread.
"""

from .client import ArcosClient, ArcosClientConfig, ConnectionState, RobotInfo
from .errors import (
    ArcosConfigError,
    ArcosDisconnectedError,
    ArcosError,
    ArcosProtocolError,
    ArcosTimeoutError,
    ControllerResetError,
    HandshakeError,
)
from .odometry import OdometrySample, RobotParams, SonarSample, params_for_subclass

__all__ = [
    "ArcosClient",
    "ArcosClientConfig",
    "ArcosConfigError",
    "ArcosDisconnectedError",
    "ArcosError",
    "ArcosProtocolError",
    "ArcosTimeoutError",
    "ConnectionState",
    "ControllerResetError",
    "HandshakeError",
    "OdometrySample",
    "RobotInfo",
    "RobotParams",
    "SonarSample",
    "params_for_subclass",
]
