"""Errors of the ARCOS/P2OS driver, rooted at :class:`ArcosError` under the shared hierarchy."""

from __future__ import annotations

from drivers.errors import (
    ChecksumError,
    ConfigError,
    DisconnectedError,
    DriverError,
    DriverTimeoutError,
    ProtocolError,
)


class ArcosError(DriverError):
    """Root of every error the Pioneer (ARCOS/P2OS) driver raises."""


class ArcosTimeoutError(ArcosError, DriverTimeoutError):
    """A handshake step, a reply or a SIP did not come in time."""


class ArcosDisconnectedError(ArcosError, DisconnectedError):
    """The link to the controller is gone (port closed, SIPs stopped, controller reset)."""


class ArcosConfigError(ArcosError, ConfigError):
    """A driver parameter or command argument is out of its legal range."""


class ArcosProtocolError(ArcosError, ProtocolError):
    """The controller sent bytes the protocol does not allow (raw bytes kept in ``raw``)."""


class ArcosChecksumError(ArcosProtocolError, ChecksumError):
    """A frame failed its checksum."""


class HandshakeError(ArcosProtocolError):
    """SYNC0/1/2 did not complete within the bounded number of retries."""


class ControllerResetError(ArcosDisconnectedError):
    """The controller sent a reset packet (0xFF/0xFE): the session is gone."""
