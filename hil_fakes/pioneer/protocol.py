"""ARCOS framing for the fake Pioneer: checksums, packets, the host's command frames and their
arguments (independent of drivers/p2os)."""

from __future__ import annotations

DIST_CONV_MM = {"p3dx": 0.485, "p3dx-sh": 1.0}


def arcos_checksum(payload: bytes) -> int:
    total = 0
    pairs = len(payload) // 2
    for k in range(pairs):
        total += payload[2 * k] * 256 + payload[2 * k + 1]
    total %= 65536
    if len(payload) % 2:
        total ^= payload[-1]
    return total


def arcos_packet(payload: bytes) -> bytes:
    chk = arcos_checksum(payload)
    return bytes([0xFA, 0xFB, len(payload) + 2]) + payload + bytes([chk // 256, chk % 256])


class _HostFrames:
    """The controller's receive side: header hunt, unsigned count, checksum; bad frames are counted."""

    def __init__(self) -> None:
        self.buf = bytearray()
        self.bad_checksum = 0

    def feed(self, data: bytes) -> list[bytes]:
        self.buf.extend(data)
        out: list[bytes] = []
        while True:
            i = self.buf.find(b"\xfa\xfb")
            if i < 0:
                del self.buf[: max(0, len(self.buf) - 1)]
                return out
            del self.buf[:i]
            if len(self.buf) < 3:
                return out
            n = self.buf[2]
            if n < 3:
                del self.buf[:2]
                continue
            if len(self.buf) < n + 3:
                return out
            body = bytes(self.buf[3 : 3 + n - 2])
            chk = self.buf[1 + n] * 256 + self.buf[2 + n]
            if chk != arcos_checksum(body):
                self.bad_checksum += 1
                del self.buf[:2]
                continue
            del self.buf[: n + 3]
            out.append(body)


def _arg(body: bytes) -> int | None:
    """The signed integer argument of a command body, None if it has none."""
    if len(body) >= 4 and body[1] in (0x3B, 0x1B):
        magnitude = body[2] | (body[3] << 8)
        return magnitude if body[1] == 0x3B else -magnitude
    return None


# command numbers (fact sheet 1.5)
SYNC0, SYNC1, SYNC2 = 0, 1, 2


PULSE, OPEN, CLOSE = 0, 1, 2


ENABLE, SETA, SETV, SETO, ROTATE, SETRV, VEL, CONFIG, ENCODER = 4, 5, 6, 7, 9, 10, 11, 18, 19


RVEL, SETRA, SONAR, STOP, VEL2, HOSTBAUD, E_STOP, BATTERYINFO, RESET = 21, 23, 28, 29, 32, 50, 55, 62, 253


IOREQUEST = 40


_KNOWN_OTHERS = {3, 8, 12, 13, 15, 17, 22, 30, 44, 56, 58, 90, 92}
