"""Errors of the SNC-RZ50 driver (VISCA control and HTTP capture).

``ViscaError`` is the package root under :class:`drivers.errors.DriverError`; each camera error
reply has its own class so a caller can catch exactly what it can handle, and every one keeps the
socket, the raw error code and the raw reply bytes.
"""

from __future__ import annotations

from drivers.errors import (
    ConfigError,
    DeviceStatusError,
    DisconnectedError,
    DriverError,
    DriverTimeoutError,
    ProtocolError,
)


class ViscaError(DriverError):
    """Root of every error this package raises."""


class ViscaConfigError(ViscaError, ConfigError):
    """A parameter is out of its legal range (raised before any byte is sent)."""


class ViscaTimeoutError(ViscaError, DriverTimeoutError):
    """No (matching) reply within the phase's timeout."""


class ViscaDisconnectedError(ViscaError, DisconnectedError):
    """The VISCA port or the HTTP camera went away."""


class ViscaProtocolError(ViscaError, ProtocolError):
    """The camera sent bytes the protocol does not allow (bad framing, wrong layout, bad nibble)."""


class ViscaReplyError(ViscaError, DeviceStatusError):
    """The camera answered a request with an error reply ``y0 6s cc FF``.

    ``socket`` is the socket nibble of the reply (0 when the error carries none), ``code`` the error
    byte as two hex digits (e.g. ``"41"``), ``raw`` the whole reply.
    """

    def __init__(self, message: str, *, socket: int, code: str, raw: bytes) -> None:
        super().__init__(message, code=code, raw=raw)
        self.socket = socket


class MessageLengthError(ViscaReplyError):
    """``60 01``: packet too long or malformed."""


class SyntaxReplyError(ViscaReplyError):
    """``60 02``: unknown command or an illegal parameter."""


class BufferFullError(ViscaReplyError):
    """``60 03``: both command sockets are busy."""


class CommandCancelledError(ViscaReplyError):
    """``6y 04``: the command in socket y was cancelled."""


class NoSocketError(ViscaReplyError):
    """``6y 05``: a cancel named an empty socket."""


class NotExecutableError(ViscaReplyError):
    """``6y 41``: the command cannot run now (out of range, wrong mode)."""


class UnknownReplyError(ViscaReplyError):
    """An error reply with a code this driver does not know (kept raw)."""


class HttpCameraError(ViscaError):
    """The camera's HTTP interface answered with an error status (``status`` keeps it)."""

    def __init__(self, message: str, *, status: int | None = None) -> None:
        super().__init__(message)
        self.status = status


class AuthenticationError(HttpCameraError):
    """HTTP 401/403: wrong or missing credentials, or not enough access level."""


class MjpegFormatError(ViscaProtocolError):
    """The MJPEG stream broke its multipart framing (kept raw)."""


__all__ = [
    "AuthenticationError",
    "BufferFullError",
    "CommandCancelledError",
    "HttpCameraError",
    "MessageLengthError",
    "MjpegFormatError",
    "NoSocketError",
    "NotExecutableError",
    "SyntaxReplyError",
    "UnknownReplyError",
    "ViscaConfigError",
    "ViscaDisconnectedError",
    "ViscaError",
    "ViscaProtocolError",
    "ViscaReplyError",
    "ViscaTimeoutError",
]
