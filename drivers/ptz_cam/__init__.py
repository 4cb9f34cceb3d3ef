"""Sony SNC-RZ50 PTZ camera: VISCA control (serial, TCP or HTTP pass-through) and JPEG/MJPEG over HTTP.

* :mod:`.visca` - sans-I/O VISCA codec (replies -> typed events, command/inquiry builders, decoders)
* :mod:`.mjpeg` - sans-I/O multipart MJPEG parser
* :mod:`.config` - link config and calibration (counts <-> radians, zoom -> FOV, intrinsics)
* :mod:`.client` - :class:`ViscaClient` (reply matching by socket and kind, scaled timeouts)
* :mod:`.frames` - :class:`MjpegFrameSource` (reader thread, reconnect) and one-shot JPEG
* :mod:`.errors` - :class:`ViscaError` and its specialisations
"""

from .client import CommandHandle, ViscaClient
from .config import CameraIntrinsics, HttpConfig, PtzCalibration, ViscaConfig
from .errors import ViscaError
from .frames import CameraFrame, MjpegFrameSource, fetch_oneshot, inquiry_system
from .state import PtzState

__all__ = [
    "CameraFrame",
    "CameraIntrinsics",
    "CommandHandle",
    "HttpConfig",
    "MjpegFrameSource",
    "PtzCalibration",
    "PtzState",
    "ViscaClient",
    "ViscaConfig",
    "ViscaError",
    "fetch_oneshot",
    "inquiry_system",
]
