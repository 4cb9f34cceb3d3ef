"""Hokuyo UTM-30LX over SCIP 2.0: a sans-I/O codec, a threaded client, USB discovery.

See ``docs/scanner.md`` for the user manual and ``shared/protocols/scip2_utm30lx.md`` for the
protocol facts this is built on.
"""

from .client import ClientConfig, ClientStats, ConnectionState, LaserScan, SensorInfo, Utm30lxClient, tcp_url
from .codec import ScipDecoder, SensorParameters, SensorState, Status, StatusMeaning, VersionInfo
from .discovery import HOKUYO_VENDOR_ID, DiscoveryResult, ScannerDevice, discover
from .errors import (
    ScipChecksumError,
    ScipConfigError,
    ScipDisconnectedError,
    ScipError,
    ScipProtocolError,
    ScipStateError,
    ScipStatusError,
    ScipTimeoutError,
    UsbBackendMissingError,
)

__all__ = [
    "HOKUYO_VENDOR_ID",
    "ClientConfig",
    "ClientStats",
    "ConnectionState",
    "DiscoveryResult",
    "LaserScan",
    "ScannerDevice",
    "ScipChecksumError",
    "ScipConfigError",
    "ScipDecoder",
    "ScipDisconnectedError",
    "ScipError",
    "ScipProtocolError",
    "ScipStateError",
    "ScipStatusError",
    "ScipTimeoutError",
    "SensorInfo",
    "SensorParameters",
    "SensorState",
    "Status",
    "StatusMeaning",
    "UsbBackendMissingError",
    "Utm30lxClient",
    "VersionInfo",
    "discover",
    "tcp_url",
]
