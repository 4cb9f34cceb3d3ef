"""HTTP plumbing for the SNC-RZ50 (stdlib ``http.client`` only): URLs, Basic auth, the VISCA pass-through.

:class:`HttpViscaPort` lets :class:`drivers.ptz_cam.client.ViscaClient` speak VISCA through
``/command/visca-ptzf.cgi?visca=HEX``. What a real RZ50 returns from that CGI is not known [?]:
this port feeds any reply bytes the body carries (hex text, as the project's fake returns them) to
the client, and when idle asks the CGI without a packet for replies queued since (completions).
If a camera returns no reply bytes at all, commands and inquiries over this port time out; read
state over the serial port instead.
"""

from __future__ import annotations

import base64
import binascii
import http.client
import threading
import time
import urllib.parse
from dataclasses import dataclass

from .config import HttpConfig
from .errors import AuthenticationError, HttpCameraError, ViscaConfigError, ViscaDisconnectedError, ViscaTimeoutError


@dataclass(frozen=True)
class Endpoint:
    scheme: str
    host: str
    port: int
    base_path: str
    auth_header: str | None

    def connection(self, timeout_s: float) -> http.client.HTTPConnection:
        cls = http.client.HTTPSConnection if self.scheme == "https" else http.client.HTTPConnection
        return cls(self.host, self.port, timeout=timeout_s)

    def headers(self) -> dict[str, str]:
        h = {"User-Agent": "vipsm-robot ptz_cam", "Connection": "close"}
        if self.auth_header:
            h["Authorization"] = self.auth_header
        return h

    def path(self, path: str, query: dict[str, str] | None = None) -> str:
        full = self.base_path.rstrip("/") + path
        return full + ("?" + urllib.parse.urlencode(query) if query else "")


def endpoint(config: HttpConfig) -> Endpoint:
    """Parse ``config.base_url`` (credentials in the URL or in the config) into an endpoint."""
    url = urllib.parse.urlsplit(config.base_url)
    if url.scheme not in ("http", "https") or not url.hostname:
        raise ViscaConfigError(f"camera HTTP URL must be http://[user:pw@]host[:port], got {config.base_url!r}")
    user = config.username if config.username is not None else url.username
    password = config.password if config.password is not None else url.password
    auth = None
    if user is not None:
        token = base64.b64encode(f"{urllib.parse.unquote(user)}:{urllib.parse.unquote(password or '')}".encode())
        auth = "Basic " + token.decode()
    port = url.port or (443 if url.scheme == "https" else 80)
    return Endpoint(url.scheme, url.hostname, port, url.path, auth)


def check_status(status: int, what: str) -> None:
    if status in (401, 403):
        raise AuthenticationError(f"{what}: HTTP {status} (wrong credentials or access level)", status=status)
    if not 200 <= status < 300:
        raise HttpCameraError(f"{what}: HTTP {status}", status=status)


def get(ep: Endpoint, path: str, timeout_s: float, query: dict[str, str] | None = None) -> tuple[int, bytes, str]:
    """One GET; returns (status, body, content type). Maps socket failures to typed errors."""
    conn = ep.connection(timeout_s)
    try:
        conn.request("GET", ep.path(path, query), headers=ep.headers())
        resp = conn.getresponse()
        return resp.status, resp.read(), resp.getheader("Content-Type") or ""
    except TimeoutError as exc:
        raise ViscaTimeoutError(f"GET {path}: no answer within {timeout_s:.1f} s") from exc
    except (OSError, http.client.HTTPException) as exc:
        raise ViscaDisconnectedError(f"GET {path}: {exc}") from exc
    finally:
        conn.close()


def parse_hex_reply(body: bytes) -> bytes:
    """VISCA reply bytes from a pass-through body written as hex text; b'' when it carries none."""
    text = body.decode("latin-1").strip().replace(" ", "").replace("\r", "").replace("\n", "")
    if not text or len(text) % 2:
        return b""
    try:
        return binascii.unhexlify(text)
    except (binascii.Error, ValueError):
        return b""


class HttpViscaPort:
    """A VISCA byte port over ``visca-ptzf.cgi`` (see the module docstring)."""

    def __init__(self, url: str, config: HttpConfig, poll_interval_s: float = 0.1) -> None:
        self.config = config if config.base_url == url else HttpConfig(**{**config.__dict__, "base_url": url})
        self._ep = endpoint(self.config)
        self._lock = threading.Lock()
        self._rx = bytearray()
        self._last_request_s = 0.0
        self._poll_interval_s = poll_interval_s
        self._closed = False
        self.requests = 0

    def _request(self, packet: bytes) -> None:
        query = {"visca": packet.hex().upper()} if packet else None
        with self._lock:
            status, body, _ = get(self._ep, self.config.passthrough_path, self.config.timeout_s, query)
            self.requests += 1
            self._last_request_s = time.monotonic()
            check_status(status, "visca-ptzf.cgi")
            self._rx += parse_hex_reply(body)

    def write(self, data: bytes) -> None:
        if self._closed:
            raise ViscaDisconnectedError("HTTP VISCA port closed")
        self._request(data)

    def read_some(self) -> bytes:
        if self._closed:
            raise ViscaDisconnectedError("HTTP VISCA port closed")
        with self._lock:
            if self._rx:
                data = bytes(self._rx)
                self._rx.clear()
                return data
        if time.monotonic() - self._last_request_s >= self._poll_interval_s:
            try:
                self._request(b"")
            except ViscaTimeoutError:
                return b""  # a slow idle poll is not a lost camera; the next one tries again
        else:
            time.sleep(0.01)
        return b""

    def close(self) -> None:
        self._closed = True
