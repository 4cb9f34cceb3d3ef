"""The error hierarchy shared by every driver package.

Each driver defines its own root (``ScipError``, ``ArcosError``, ``ViscaError``) that derives from
:class:`DriverError`, and specialises the kinds below, so a caller can catch per device or across
devices. A timeout is also the builtin :class:`TimeoutError`; a lost link is also a
:class:`ConnectionError`.
"""

from __future__ import annotations


class DriverError(Exception):
    """Root of every error a driver raises."""


class DriverTimeoutError(DriverError, TimeoutError):
    """A blocking call ran out of its finite timeout."""


class DisconnectedError(DriverError, ConnectionError):
    """The port is gone (unplugged, closed by the peer, or never opened)."""


class ConfigError(DriverError, ValueError):
    """A driver parameter is out of its legal range (caught before any byte is sent)."""


class ProtocolError(DriverError):
    """The device sent something the protocol does not allow.

    ``code`` keeps the raw status or error code as the device sent it (a string, never parsed as a
    number); ``raw`` keeps the offending bytes.
    """

    def __init__(self, message: str, *, code: str | None = None, raw: bytes = b"") -> None:
        super().__init__(message)
        self.code = code
        self.raw = bytes(raw)


class ChecksumError(ProtocolError):
    """A frame or line failed its checksum."""


class DeviceStatusError(ProtocolError):
    """The device answered a request with an error status (kept raw in ``code``)."""
