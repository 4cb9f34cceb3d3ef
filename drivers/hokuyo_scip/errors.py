"""Errors of the UTM-30LX (SCIP 2.0) driver, specialising the shared :mod:`drivers.errors` kinds.

Catch :class:`ScipError` for everything this driver raises, or the shared kinds
(:class:`~drivers.errors.DriverTimeoutError`, :class:`~drivers.errors.DisconnectedError`, ...)
across drivers.
"""

from __future__ import annotations

from drivers.errors import (
    ChecksumError,
    ConfigError,
    DeviceStatusError,
    DisconnectedError,
    DriverError,
    DriverTimeoutError,
    ProtocolError,
)


class ScipError(DriverError):
    """Root of every error the UTM-30LX driver raises."""


class ScipProtocolError(ScipError, ProtocolError):
    """A reply that breaks SCIP 2.0 framing or layout (keeps the raw code and bytes)."""


class ScipChecksumError(ScipProtocolError, ChecksumError):
    """A status, info, timestamp or data line failed its checksum."""


class ScipStatusError(ScipProtocolError, DeviceStatusError):
    """The sensor answered with a status outside the command's success set (``code`` is the raw string)."""

    def __init__(self, message: str, *, code: str | None = None, raw: bytes = b"", command: str = "") -> None:
        super().__init__(message, code=code, raw=raw)
        self.command = command


class ScipTimeoutError(ScipError, DriverTimeoutError):
    """No (complete) reply within the call's timeout."""


class ScipDisconnectedError(ScipError, DisconnectedError):
    """The sensor's port vanished (unplug, closed socket) or could not be opened."""


class ScipConfigError(ScipError, ConfigError):
    """A parameter out of its legal range, rejected before any byte is sent."""


class ScipStateError(ScipError):
    """The call does not fit the client's state (e.g. a command while streaming, or a closed client)."""


class UsbBackendMissingError(ScipError):
    """pyusb has no libusb backend on this system, so USB discovery cannot run."""
