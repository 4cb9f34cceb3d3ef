"""``live.listen``: the live view's address parsed and checked, with nothing else imported, so the
config can check it when it is loaded (:class:`app.config.LiveConfig`) without importing the live
view itself."""

from __future__ import annotations

import ipaddress
import re

from .errors import ConfigError

DEFAULT_HOST = "127.0.0.1"


_PORT = re.compile(r"[0-9]{1,5}")  # ASCII digits only (int() would take "8_765" and "８７６５")
_HOST = re.compile(r"[A-Za-z0-9]([A-Za-z0-9.-]*[A-Za-z0-9])?")  # a host name or an IPv4 address


def parse_listen(spec: str) -> tuple[str, int]:
    """``[HOST:]PORT`` -> (host, port); host 127.0.0.1 when left out; an IPv6 host in brackets,
    ``[::1]:8765``. ConfigError (key ``live.listen``) for anything else."""
    text = spec.strip()
    if text.startswith("["):
        host, sep, port_text = text[1:].partition("]:")
        try:
            ipaddress.IPv6Address(host)
        except ValueError:
            sep = ""
        if not sep:
            raise ConfigError("live.listen", f"{spec!r}: expected [IPV6-ADDRESS]:PORT, e.g. [::1]:8765")
    elif text.count(":") > 1:
        raise ConfigError("live.listen", f"{spec!r}: an IPv6 host needs brackets and a port, e.g. [::1]:8765")
    else:
        host, sep, port_text = text.rpartition(":")
        host = host if sep else DEFAULT_HOST
        if not _HOST.fullmatch(host):
            raise ConfigError("live.listen", f"{spec!r}: expected [HOST:]PORT, e.g. 8765 or 127.0.0.1:8765 (HOST a "
                                             "name or an IPv4 address; an IPv6 address in brackets)")
    if not _PORT.fullmatch(port_text) or int(port_text) > 65535:
        raise ConfigError("live.listen", f"{spec!r}: the port must be 0-65535 in ASCII digits (0: any free port)")
    return host, int(port_text)


def is_loopback(host: str) -> bool:
    try:
        return host == "localhost" or ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False  # a host name may resolve to any interface


def check_exposure(host: str, allow_remote: bool) -> str:
    """'' on loopback; a warning when a remote address is allowed; ConfigError when it is not."""
    if is_loopback(host):
        return ""
    if not allow_remote:
        raise ConfigError("live.listen", f"a live view on {host!r} is reachable from the network: refused unless "
                                         "config key 'live.allow_remote' is true")
    return (f"live view on {host!r}: scans, pose, obstacles and camera images are readable by anyone who can "
            "reach this port (live.allow_remote = true)")
