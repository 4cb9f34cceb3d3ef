"""The fake Pioneer against raw bytes from the fact sheet (no driver code involved).

Most tests drive the model directly on a simulated clock (deterministic, no threads); one runs the
command sequence ARIA's simpleConnect was observed to send, over TCP.
"""

from __future__ import annotations

import math
import socket
import struct
import time
from collections.abc import Callable

import pytest

from hil_fakes.pioneer import FakePioneer, PioneerConfig, RectangularRoom, serve
from hil_fakes.wheel_odometry import OdometryNoise

H = bytes.fromhex


def chk(payload: bytes) -> bytes:
    """Checksum written out from the fact sheet for this test (independent of both codec and fake)."""
    c = 0
    for i in range(0, len(payload) - 1, 2):
        c = (c + (payload[i] << 8) + payload[i + 1]) & 0xFFFF
    if len(payload) % 2:
        c ^= payload[-1]
    return bytes((c >> 8, c & 0xFF))


def pkt(payload: bytes) -> bytes:
    return b"\xfa\xfb" + bytes((len(payload) + 2,)) + payload + chk(payload)


def cmd_int(cmd: int, value: int) -> bytes:
    return pkt(bytes((cmd, 0x3B if value >= 0 else 0x1B)) + struct.pack("<H", abs(value)))


def test_the_test_checksum_matches_the_worked_frames() -> None:
    assert pkt(b"\x04\x3b\x01\x00") == H("FA FB 06 04 3B 01 00 05 3B")
    assert cmd_int(11, -200) == H("FA FB 06 0B 1B C8 00 D3 1B")
    assert cmd_int(6, 400) == H("FA FB 06 06 3B 90 01 96 3C")


def frames(data: bytes) -> list[bytes]:
    """Payloads of all well-formed frames in ``data`` (checksums verified)."""
    out = []
    i = 0
    while True:
        i = data.find(b"\xfa\xfb", i)
        if i < 0 or i + 3 > len(data):
            return out
        n = data[i + 2]
        body = data[i + 3 : i + 1 + n]
        if i + 3 + n <= len(data) and n >= 3 and chk(body) == data[i + 1 + n : i + 3 + n]:
            out.append(body)
            i += 3 + n
        else:
            i += 2


def sip_fields(body: bytes) -> dict[str, int]:
    t, x, y, th, lv, rv, batt, stall, control, flags, compass, n = struct.unpack_from("<BHHhhhBHhHBB", body)
    return {"type": t, "x": x & 0x7FFF, "y": y & 0x7FFF, "th": th, "lv": lv, "rv": rv, "flags": flags, "n": n}


class Sim:
    """The model on a simulated clock, its output collected."""

    def __init__(self, **cfg: object) -> None:
        self.model = FakePioneer(PioneerConfig(**cfg))  # type: ignore[arg-type]
        self.out = bytearray()
        self.model.attach(self.out.extend)
        self.t = 100.0
        self.model.poll(self.t)

    def send(self, data: bytes) -> list[bytes]:
        self.out.clear()
        self.model.on_bytes(data, self.t)
        return frames(bytes(self.out))

    def run(self, seconds: float, dt: float = 0.01) -> list[bytes]:
        self.out.clear()
        end = self.t + seconds
        while self.t < end - 1e-9:
            self.t += dt
            self.model.poll(self.t)
        return frames(bytes(self.out))

    def connect(self) -> None:
        assert self.send(H("FA FB 03 00 00 00")) == [b"\x00"]
        assert self.send(H("FA FB 03 01 00 01")) == [b"\x01"]
        (ident,) = self.send(H("FA FB 03 02 00 02"))
        assert ident[0] == 2
        self.send(H("FA FB 03 01 00 01"))  # OPEN

    def sips(self, payloads: list[bytes]) -> list[dict[str, int]]:
        return [sip_fields(p) for p in payloads if p[0] in (0x32, 0x33)]


def test_handshake_identity_and_sip_stream_at_the_cycle() -> None:
    sim = Sim(name="UNR_63", subclass="p3dx-sh")
    assert sim.run(0.5) == []  # nothing before the handshake
    assert sim.send(H("FA FB 03 00 00 00")) == [b"\x00"]
    assert sim.send(H("FA FB 03 01 00 01")) == [b"\x01"]
    assert sim.send(H("FA FB 03 02 00 02")) == [b"\x02UNR_63\x00Pioneer\x00p3dx-sh\x00"]
    assert sim.run(0.5) == []  # no SIPs before OPEN
    sim.send(cmd_int(1, 1))  # ARIA sends OPEN with an int argument
    sips = sim.sips(sim.run(1.0))
    assert len(sips) == 10  # one every 100 ms
    assert sips[0]["flags"] & 1 == 0  # motors disabled until ENABLE
    assert all(s["type"] == 0x32 for s in sips)


def test_out_of_order_sync_restarts_at_sync0() -> None:
    sim = Sim()
    assert sim.send(H("FA FB 03 01 00 01")) == []  # SYNC1 first: ignored, back to SYNC0
    assert sim.send(H("FA FB 03 00 00 00")) == [b"\x00"]
    assert sim.send(H("FA FB 03 02 00 02")) == []  # skipped SYNC1: restart
    assert sim.model.stats.sync_restarts == 2
    sim.model.misorder_sync(1)
    assert sim.send(H("FA FB 03 00 00 00")) == [b"\x01"]  # injected wrong echo


def test_bad_checksum_commands_are_ignored() -> None:
    sim = Sim()
    sim.connect()
    sim.send(cmd_int(4, 1))
    bad = bytearray(cmd_int(11, 300))
    bad[-1] ^= 0xFF
    sim.send(bytes(bad))
    assert sim.model.stats.bad_checksum == 1
    assert sim.model.setpoint == (0.0, 0.0)


def test_motors_disabled_until_enable_then_drive_with_accel_limits() -> None:
    sim = Sim()
    sim.connect()
    sim.send(cmd_int(11, 300))
    sips = sim.sips(sim.run(0.5))
    assert all(s["lv"] == 0 and s["rv"] == 0 for s in sips)
    sim.send(cmd_int(4, 1))
    sim.send(cmd_int(11, 300))
    sips = sim.sips(sim.run(2.0))
    assert sips[-1]["flags"] & 1 == 1
    assert sips[0]["lv"] < 300  # ramping up at 300 mm/s^2
    assert sips[-1]["lv"] == sips[-1]["rv"] == 300 and sips[-1]["type"] == 0x33
    x, y, th, v, w = sim.model.truth(sim.t)
    assert v == pytest.approx(0.3) and x > 0.3 and y == 0.0


def test_rvel_and_wheel_speeds_and_rotvel() -> None:
    sim = Sim(rot_accel_degps2=300)
    sim.connect()
    sim.send(cmd_int(4, 1) + cmd_int(21, -10))
    payloads = sim.run(1.0)
    body = [p for p in payloads if p[0] in (0x32, 0x33)][-1]
    f = sip_fields(body)
    assert f["rv"] < 0 < f["lv"]  # clockwise: right wheel backwards
    rotvel = struct.unpack_from("<h", body, 20 + 3 * f["n"] + 5 + 3)[0]
    assert rotvel == -100  # 0.1 deg/s units


def test_vel2_high_byte_left_low_byte_right() -> None:
    sim = Sim(trans_accel_mmps2=2000, rot_accel_degps2=300)
    sim.connect()
    sim.send(cmd_int(4, 1) + H("FA FB 06 20 1B FB 04 1B 1F"))  # left -5, right +5 (x 20 mm/s)
    v, w = sim.model.setpoint
    assert v == 0.0 and w == pytest.approx(math.degrees(100 * 0.0056))


def test_counters_wrap_at_15_bits_and_heading_at_4096() -> None:
    sim = Sim(start_x_counts=32500, start_th_units=4000, trans_accel_mmps2=2000, rot_accel_degps2=300)
    sim.connect()
    sim.send(cmd_int(4, 1) + cmd_int(11, 200) + cmd_int(21, 5))
    sips = sim.sips(sim.run(3.0))
    xs = [s["x"] for s in sips]
    ths = [s["th"] for s in sips]
    assert max(xs) > 32000 and min(xs) < 1000
    assert all(0 <= t < 4096 for t in ths) and max(ths) > 4000 and min(ths) < 100
    assert sim.model.stats.x_wraps == 1 and sim.model.stats.th_wraps == 1


def test_signed_heading_option() -> None:
    sim = Sim(start_th_units=1950, heading_signed=True, rot_accel_degps2=300)
    sim.connect()
    sim.send(cmd_int(4, 1) + cmd_int(21, 10))
    ths = [s["th"] for s in sim.sips(sim.run(2.0))]
    assert max(ths) <= 2047 and min(ths) >= -2048 and min(ths) < 0 < max(ths)


def test_raw_xy_are_integrated_in_the_raw_heading_frame() -> None:
    # raw heading 90 deg: driving forward moves raw +y, never raw x (the fact sheet's "lesson")
    sim = Sim(start_x_counts=1000, start_y_counts=1000, start_th_units=1024, subclass="p3dx-sh")
    sim.connect()
    sim.send(cmd_int(4, 1) + cmd_int(11, 200))
    last = sim.sips(sim.run(2.0))[-1]
    assert abs(last["x"] - 1000) <= 1 and last["y"] > 1200
    rx, ry, rth = sim.model.raw_odometry_pose()
    tx, ty, _, _, _ = sim.model.truth(sim.t)
    assert (rx - 1.0, ry - 1.0) == pytest.approx((-ty, tx), abs=1e-9)


def test_watchdog_stops_and_resumes_the_old_setpoint() -> None:
    sim = Sim(watchdog_s=2.0, watchdog_resume=True)
    sim.connect()
    sim.send(cmd_int(4, 1) + cmd_int(11, 200))
    sim.run(1.9)
    assert sim.model.truth(sim.t)[3] == pytest.approx(0.2)
    sim.run(1.5)
    assert sim.model.stats.watchdog_trips == 1 and sim.model.truth(sim.t)[3] == 0.0
    sim.send(H("FA FB 03 00 00 00"))  # a PULSE: traffic returns, the stale setpoint resumes
    sim.run(1.0)
    assert sim.model.truth(sim.t)[3] == pytest.approx(0.2)


def test_watchdog_without_resume_stays_stopped() -> None:
    sim = Sim(watchdog_s=1.0, watchdog_resume=False)
    sim.connect()
    sim.send(cmd_int(4, 1) + cmd_int(11, 200))
    sim.run(3.0)
    sim.send(H("FA FB 03 00 00 00"))
    sim.run(1.0)
    assert sim.model.truth(sim.t)[3] == 0.0 and sim.model.setpoint == (0.0, 0.0)


def test_pulses_keep_the_watchdog_fed() -> None:
    sim = Sim(watchdog_s=1.0)
    sim.connect()
    sim.send(cmd_int(4, 1) + cmd_int(11, 200))
    for _ in range(10):
        sim.run(0.5)
        sim.send(H("FA FB 03 00 00 00"))
    assert sim.model.stats.watchdog_trips == 0 and sim.model.truth(sim.t)[3] == pytest.approx(0.2)


def test_seto_stop_estop_and_close() -> None:
    sim = Sim(trans_accel_mmps2=2000)
    sim.connect()
    sim.send(cmd_int(4, 1) + cmd_int(11, 500))
    sim.run(1.0)
    sim.send(H("FA FB 03 07 00 07"))  # SETO
    assert sim.model.raw_odometry_pose() == (0.0, 0.0, 0.0)
    sim.send(H("FA FB 03 37 00 37"))  # E_STOP
    assert sim.model.truth(sim.t)[3] == 0.0
    assert sim.sips(sim.run(0.2))[-1]["flags"] & 0x20
    sim.send(cmd_int(11, 300))
    sim.run(0.5)
    sim.send(pkt(b"\x1d"))  # STOP
    sim.run(2.0)
    assert sim.model.truth(sim.t)[3] == 0.0
    sim.send(cmd_int(2, 1))  # CLOSE with an argument (ARIA)
    assert sim.model.state == "sync0" and sim.run(0.5) == []


def test_config_packet_layout_and_encoder_stream() -> None:
    sim = Sim(watchdog_s=2.0, subclass="p3dx-sh", name="FAPESP_3156")
    sim.connect()
    (cfg,) = [p for p in sim.send(H("FA FB 06 12 3B 01 00 13 3B")) if p[0] == 0x20]
    parts = cfg[1:].split(b"\x00", 3)
    assert parts[:3] == [b"Pioneer", b"p3dx-sh", b"FAKE0001"]
    rest = parts[3]
    assert rest[0] == 0  # 4MOTS
    rot_top, trans_top = struct.unpack_from("<HH", rest, 1)
    assert (rot_top, trans_top) == (360, 1500)
    name_end = rest.index(b"\x00", 11)
    assert rest[11:name_end] == b"FAPESP_3156"
    sip_cycle, host_baud = rest[name_end + 1], rest[name_end + 2]
    assert (sip_cycle, host_baud) == (100, 0)
    watchdog = struct.unpack_from("<H", rest, name_end + 4 + 5 + 4)[0]
    assert watchdog == 2000
    sim.send(H("FA FB 06 13 3B 02 00 15 3B"))  # ENCODER 2
    enc = [p for p in sim.run(0.35) if p[0] == 0x90]
    assert len(enc) == 3 and all(len(p) == 9 for p in enc)


def test_sonar_ranges_in_the_default_room() -> None:
    room = RectangularRoom()
    sim = Sim()
    sim.connect()
    body = [p for p in sim.run(0.15) if p[0] in (0x32, 0x33)][-1]
    n = body[19]
    readings = {body[20 + 3 * k]: struct.unpack_from("<H", body, 21 + 3 * k)[0] for k in range(n)}
    assert n == 16 and sorted(readings) == list(range(16))
    assert readings[0] == round((room.y_max_m - 0.136) * 1000)  # sonar 0 looks left at y=+136 mm
    assert readings[4] == 5000  # forward wall beyond the 5 m sonar range
    sim.send(cmd_int(28, 0))  # SONAR 0
    body = [p for p in sim.run(0.15) if p[0] in (0x32, 0x33)][-1]
    assert body[19] == 0


@pytest.mark.parametrize(("tail", "length"), [("none", 20 + 48), ("digout", 20 + 48 + 5), ("arcos", 20 + 48 + 12)])
def test_sip_tail_options(tail: str, length: int) -> None:
    sim = Sim(sip_tail=tail)
    sim.connect()
    body = [p for p in sim.run(0.15) if p[0] in (0x32, 0x33)][-1]
    assert len(body) == length


def test_reset_packet_and_stale_session() -> None:
    sim = Sim(start_open=True)
    assert len(sim.sips(sim.run(0.5))) == 5  # streaming without any handshake: a stale session
    assert sim.send(H("FA FB 03 00 00 00")) == []  # SYNC0 into an open session is a PULSE
    sim.send(H("FA FB 03 02 00 02"))  # CLOSE
    sim.connect()
    sim.out.clear()
    sim.model.send_reset_packet()
    assert frames(bytes(sim.out)) == [b"\xff"]
    assert sim.model.state == "sync0" and sim.run(0.3) == []


def test_odometry_noise_reaches_the_counters() -> None:
    sim = Sim(odometry_noise=OdometryNoise(scale_error=0.1), subclass="p3dx-sh", trans_accel_mmps2=2000)
    sim.connect()
    sim.send(cmd_int(4, 1) + cmd_int(11, 500))
    sim.run(2.0)
    sim.send(cmd_int(11, 0))
    last = sim.sips(sim.run(1.0))[-1]
    true_x = sim.model.truth(sim.t)[0]
    assert last["x"] == pytest.approx(true_x * 1000 * 1.1, abs=1.0)


def test_aria_simple_connect_sequence_over_tcp() -> None:
    """The command sequence ARIA's simpleConnect was observed to send (fact sheet 1.4), as raw bytes."""
    model = FakePioneer()
    server = serve(model, tcp="127.0.0.1:0")
    try:
        port = int(server.address.rsplit(":", 1)[1])
        with socket.create_connection(("127.0.0.1", port), timeout=5.0) as sock:
            sock.settimeout(0.2)
            buf = bytearray()

            def exchange(data: bytes, wait_s: float = 0.3, min_frames: int = 0) -> list[bytes]:
                """Send, then collect for ``wait_s`` (longer, up to 5 s, until ``min_frames`` came)."""
                buf.clear()
                sock.sendall(data)
                start = time.monotonic()
                while True:
                    elapsed = time.monotonic() - start
                    if elapsed >= 5.0 or (elapsed >= wait_s and len(frames(bytes(buf))) >= min_frames):
                        return frames(bytes(buf))
                    try:
                        buf.extend(sock.recv(4096))
                    except TimeoutError:
                        pass

            assert exchange(H("FA FB 03 00 00 00"), min_frames=1) == [b"\x00"]
            assert exchange(H("FA FB 03 01 00 01"), min_frames=1) == [b"\x01"]
            assert exchange(H("FA FB 03 02 00 02"), min_frames=1) == [b"\x02fakebot\x00Pioneer\x00p3dx\x00"]
            replies = exchange(cmd_int(1, 1) + H("FA FB 06 12 3B 01 00 13 3B"), wait_s=0.5, min_frames=2)
            assert any(p[0] == 0x20 for p in replies) and any(p[0] in (0x32, 0x33) for p in replies)
            sequence = (
                cmd_int(62, 1)  # BATTERYINFO
                + H("FA FB 06 04 3B 01 00 05 3B")  # ENABLE 1
                + H("FA FB 06 06 3B 90 01 96 3C")  # SETV 400
                + cmd_int(5, 300)
                + H("FA FB 06 05 1B 2C 01 31 1C")  # SETA -300
                + cmd_int(10, 100)
                + cmd_int(23, 100)
                + cmd_int(23, -100)
                + H("FA FB 03 00 00 00")  # PULSE
            )
            exchange(sequence, wait_s=0.1)

            def until(pred: Callable[[], bool], timeout_s: float = 5.0) -> bool:
                end = time.monotonic() + timeout_s
                while time.monotonic() < end:
                    if pred():
                        return True
                    exchange(b"", wait_s=0.05)
                return pred()

            def enabled_sip_seen() -> bool:
                return any(p[0] in (0x32, 0x33) and sip_fields(p)["flags"] & 1 for p in frames(bytes(buf)))

            assert until(enabled_sip_seen)  # motors enabled, reported in the SIP FLAGS
            sock.sendall(H("FA FB 06 0B 3B FA 00") + chk(H("0B 3B FA 00")))  # VEL 250
            assert until(lambda: model.truth(time.monotonic())[3] > 0.1)
            sock.sendall(cmd_int(4, 0) + cmd_int(2, 1))  # ENABLE 0, CLOSE 1
            assert until(lambda: model.state == "sync0" and not model.motors_enabled)
            exchange(b"", wait_s=0.2)  # drain what was in flight
            assert exchange(b"", wait_s=0.3) == []  # the stream stopped
        assert model.stats.bad_checksum == 0 and model.stats.unknown_commands == 0
    finally:
        server.stop()


def test_wheel_speeds_match_the_recorded_amrisim_values() -> None:
    # fact sheet 1.6: at VEL 200 / RVEL -10, AMRISim reported lvel 231, rvel 168 and ROTVEL -100
    sim = Sim(trans_accel_mmps2=2000, rot_accel_degps2=300)
    sim.connect()
    sim.send(cmd_int(4, 1) + cmd_int(11, 200) + H("FA FB 06 15 1B 0A 00 1F 1B"))
    body = [p for p in sim.run(1.0) if p[0] in (0x32, 0x33)][-1]
    f = sip_fields(body)
    assert f["lv"] == 231 and abs(f["rv"] - 168) <= 1  # AMRISim truncates 168.8, we round
    assert struct.unpack_from("<h", body, 20 + 3 * f["n"] + 8)[0] == -100
