"""The VISCA client against the fake SNC-RZ50 over a real pty and over loopback TCP.

No timed assertions: moves are checked by what the camera reports, waits use generous timeouts.
"""

from __future__ import annotations

import math
import time

import pytest

from drivers.ptz_cam import ViscaClient, ViscaConfig
from drivers.ptz_cam import visca as v
from drivers.ptz_cam.errors import (
    BufferFullError,
    CommandCancelledError,
    NoSocketError,
    NotExecutableError,
    SyntaxReplyError,
    ViscaConfigError,
    ViscaDisconnectedError,
    ViscaError,
    ViscaTimeoutError,
)
from hil_fakes.snc_rz50 import FakeCameraSpec

from .conftest import FAULTY, Rig

H = bytes.fromhex


def wait_until(cond, timeout_s: float = 10.0) -> bool:  # type: ignore[no-untyped-def]
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if cond():
            return True
        time.sleep(0.01)
    return cond()


def test_start_up_sequence(rig: Rig) -> None:
    seen = rig.camera.visca.commands_seen
    assert seen[:3] == [H("88 30 01 FF"), H("88 01 00 01 FF"), H("81 01 00 01 FF")]
    assert H("81 09 00 02 FF") in seen and H("81 09 06 11 FF") in seen
    assert H("81 01 04 06 03 FF") in seen  # digital zoom off
    c = rig.client
    assert c.camera_count == 1
    assert c.version == v.Version(0x0020, rig.camera.spec.model, rig.camera.spec.rom_version, 2)
    assert (c.pan_max_speed, c.tilt_max_speed) == (0x18, 0x14)
    assert c.last_state is not None and c.last_state.pan_counts == 0
    assert c.stats.startup_warnings == []


def test_absolute_moves_read_back_in_radians(rig: Rig) -> None:
    c = rig.client
    c.move_to(math.radians(30), math.radians(-5))
    s = c.position()
    assert (s.pan_counts, s.tilt_counts) == (-432, -72)  # 30 deg left = VISCA -432 (right positive)
    assert s.pan_deg == pytest.approx(30.0) and s.tilt_deg == pytest.approx(-5.0) and not s.moving
    c.move_to(math.radians(-90), 0, speed=0.5)
    assert c.pan_tilt_counts().pan_counts == 1296
    c.move_by(math.radians(10), math.radians(2))
    assert c.position().pan_deg == pytest.approx(-80.0, abs=0.1)
    c.home()
    assert c.pan_tilt_counts() == v.PanTiltPosition(0, 0, v.PanTiltLayout.FOUR_FOUR)


def test_every_command_and_inquiry(rig: Rig) -> None:
    c = rig.client
    c.drive(0.5, 0.0)
    assert wait_until(lambda: rig.camera.state.ptz(time.monotonic())[0] < -5)  # driving left
    c.stop()
    c.drive(-0.2, 0.3)
    c.stop()
    assert H("81 01 06 01 0C 01 01 03 FF") in rig.camera.visca.commands_seen  # idle tilt axis has speed 1
    assert H("81 01 06 01 01 01 03 03 FF") in rig.camera.visca.commands_seen  # stop with legal speeds
    c.reset()
    assert c.pan_tilt_counts().pan_counts == 0
    c.zoom_to(0x2000)
    assert c.zoom_position() == 0x2000
    c.zoom_to_magnification(1.0)
    assert c.zoom_position() == 0
    c.zoom_tele(speed=7)
    assert wait_until(lambda: rig.camera.state.ptz(time.monotonic())[2] > 100)
    c.zoom_stop()
    c.zoom_wide()
    c.zoom_stop()
    c.set_digital_zoom(True)
    assert c.digital_zoom_on() is True
    c.set_digital_zoom(False)
    assert c.digital_zoom_on() is False
    c.focus_manual()
    assert c.focus_mode() is v.FocusMode.MANUAL
    c.focus_one_push()
    c.focus_auto()
    assert c.focus_mode() is v.FocusMode.AUTO
    assert c.power() is v.PowerState.ON
    assert c.max_speed() == v.MaxSpeed(0x18, 0x14)
    assert c.read_version().vendor == 0x0020
    k = c.intrinsics(320, 240)
    assert k.width_px == 320 and k.cx_px == 160


@pytest.mark.parametrize("spec", [FakeCameraSpec(zoom_full_travel_s=4.0)])
def test_two_commands_in_flight_and_buffer_full(rig: Rig) -> None:
    c = rig.client
    pan = c.move_to(math.radians(-60), 0, speed=0.05, wait=False)  # 864 counts at 25 deg/s: 2.4 s
    zoom = c.zoom_to(0x2000, wait=False)  # 2 s: both long enough to still run for the third command
    assert {pan.socket, zoom.socket} == {1, 2}
    assert c.in_flight() == {pan.socket: "pan_tilt_absolute", zoom.socket: "zoom_direct"}
    assert c.last_state is not None and c.last_state.moving
    # inquiries go on while both sockets are busy
    assert c.focus_mode() is v.FocusMode.AUTO
    with pytest.raises(BufferFullError) as err:
        c.focus_one_push()
    assert err.value.socket == 0 and err.value.code == "03"
    pan.wait()
    zoom.wait()
    assert c.in_flight() == {}
    s = c.position()
    assert (s.pan_counts, s.zoom_position) == (864, 0x2000) and not s.moving


def test_move_slower_than_the_default_timeout(transport: str, tmp_path) -> None:  # type: ignore[no-untyped-def]
    from hil_fakes.snc_rz50 import FakeCamera

    from .conftest import make_server

    camera = FakeCamera()
    server = make_server(camera, transport, tmp_path)
    cfg = ViscaConfig(ack_timeout_s=2.0, inquiry_timeout_s=2.0, default_completion_timeout_s=0.3)
    try:
        with ViscaClient(server.address, cfg) as c:
            # 20 deg at speed 1: 1.6 s on the fake, far beyond the 0.3 s default
            h = c.move_to(math.radians(20), 0, speed=1 / 24, wait=False)
            assert h.timeout_s > 1.6
            h.wait()
            assert c.pan_tilt_counts().pan_counts == -288
            assert c.stats.timeouts == 0 and c.stats.late_completions == 0
    finally:
        server.stop()


def test_error_replies_are_typed_errors(rig: Rig) -> None:
    c = rig.client
    # out of range: ACK first, then "not executable" for that socket
    with pytest.raises(NotExecutableError) as err:
        c.command(v.pan_tilt_absolute(3000, 0))
    assert err.value.socket in (1, 2) and err.value.raw == bytes([0x90, 0x60 | err.value.socket, 0x41, 0xFF])
    # a speed of 0 (which the builders refuse) is a syntax error without ACK
    bad = v.Request("drive_speed_0", H("81 01 06 01 00 01 03 01 FF"), v.ReplyKind.COMMAND)
    with pytest.raises(SyntaxReplyError):
        c.command(bad)
    bad_inq = v.Request("bad_inq", H("81 09 7E 7E FF"), v.ReplyKind.INQUIRY, answer_lengths=(1,))
    with pytest.raises(SyntaxReplyError):
        c.inquire(bad_inq, retries=0)
    with pytest.raises(NoSocketError):
        c.cancel(2)
    with pytest.raises(NotExecutableError):
        c.focus_one_push()  # in auto focus
    with pytest.raises(ViscaConfigError):
        c.move_to(math.radians(200), 0)
    # cancel a running move: the move fails as cancelled, the camera stops short of the target
    h = c.move_to(math.radians(-150), 0, speed=0.05, wait=False)
    c.cancel(h.socket)
    with pytest.raises(CommandCancelledError):
        h.wait()
    assert abs(c.pan_tilt_counts().pan_counts) < 2160
    assert c.position().pan_counts == c.last_state.pan_counts  # type: ignore[union-attr]


@pytest.mark.parametrize("config", [FAULTY])
def test_late_completion_is_never_taken_for_the_next_answer(rig: Rig) -> None:
    c = rig.client
    rig.camera.visca.faults.late_completions = 1
    rig.camera.visca.faults.late_extra_s = 1.0
    h = c.zoom_to(0x1000, wait=False)
    with pytest.raises(ViscaTimeoutError):
        h.wait(timeout_s=0.3)
    # the late "90 5y FF" arrives while we ask other things: answers stay right
    for _ in range(10):
        assert c.zoom_position() in range(0, 0x1001)
        assert c.focus_mode() is v.FocusMode.AUTO
    assert wait_until(lambda: c.stats.late_completions == 1)
    assert c.zoom_position() == 0x1000
    c.move_to(math.radians(5), 0)  # sockets are free again
    assert c.pan_tilt_counts().pan_counts == -72


@pytest.mark.parametrize("config", [FAULTY])
def test_dropped_replies_recover(rig: Rig) -> None:
    c = rig.client
    rig.camera.visca.faults.drop_replies = 1
    assert c.zoom_position() == 0  # the inquiry is re-sent once (idempotent)
    rig.camera.visca.faults.drop_replies = 1  # the ACK of a relative move: never re-sent
    with pytest.raises(ViscaTimeoutError):
        c.move_by(math.radians(1), 0)
    assert c.pan_tilt_counts().pan_counts == -14  # moved exactly once
    rig.camera.visca.faults.drop_replies = 2  # an absolute move is re-sent after a lost ACK
    c.move_to(math.radians(2), 0)
    assert c.pan_tilt_counts().pan_counts == -29


@pytest.mark.parametrize("config", [FAULTY])
def test_garbled_and_junk_replies_recover(rig: Rig) -> None:
    c = rig.client
    rig.camera.visca.faults.garble_replies = 1
    assert c.power() is v.PowerState.ON
    rig.server.faults.junk(b"\x12\x34\x56\xff\x90\x7e\xff" + bytes(range(0x20, 0x40)))
    assert c.focus_mode() is v.FocusMode.AUTO
    rig.server.faults.corrupt(1)  # bit flip in the next reply
    try:
        c.zoom_position()
    except ViscaError:
        pass
    assert c.zoom_position() == 0
    rig.server.faults.split(chunk_bytes=1, delay_s=0.002, writes=3)
    c.move_to(math.radians(-3), math.radians(1))
    assert c.pan_tilt_counts() == v.PanTiltPosition(43, 14, v.PanTiltLayout.FOUR_FOUR)
    assert wait_until(lambda: c.stats.discarded_bytes > 0)


@pytest.mark.parametrize("config", [FAULTY])
def test_stalled_camera_times_out_then_recovers(rig: Rig) -> None:
    c = rig.client
    rig.server.faults.stall(0.8)
    with pytest.raises(ViscaTimeoutError):
        c.inquire(v.power_inquiry(), retries=0)
    assert wait_until(lambda: not rig.server.faults.stalled)
    assert c.power() is v.PowerState.ON


def test_network_change_reruns_address_set(rig: Rig) -> None:
    c = rig.client
    n = rig.camera.visca.commands_seen.count(H("88 30 01 FF"))
    rig.camera.visca.send_network_change()
    assert wait_until(lambda: c.stats.network_changes == 1)
    assert c.power() is v.PowerState.ON
    assert rig.camera.visca.commands_seen.count(H("88 30 01 FF")) == n + 1


def test_connection_drop_is_a_typed_error_then_reconnects(rig: Rig) -> None:
    c = rig.client
    c.move_to(math.radians(10), 0)
    rig.server.faults.disconnect()
    if rig.transport == "pty":
        # the pty vanished and came back behind the same link (a USB replug)
        assert wait_until(lambda: c.last_error is not None)
        assert isinstance(c.last_error, ViscaDisconnectedError)
    ok = False
    for _ in range(50):
        try:
            ok = c.power() is v.PowerState.ON
            break
        except (ViscaDisconnectedError, ViscaTimeoutError):
            time.sleep(0.1)
    assert ok
    assert c.pan_tilt_counts().pan_counts == -144  # the camera kept its position
    assert c.stats.reconnects >= (1 if rig.transport == "pty" else 0)


@pytest.mark.parametrize("spec", [FakeCameraSpec(pan_nibbles=5)])
def test_five_nibble_position_layout(rig: Rig) -> None:
    c = rig.client
    c.move_to(math.radians(-55.5), math.radians(-13.9))
    pos = c.pan_tilt_counts()
    assert pos.layout is v.PanTiltLayout.FIVE_FOUR
    assert (pos.pan_counts, pos.tilt_counts) == (799, -200)


@pytest.mark.parametrize("spec", [FakeCameraSpec(answers_version=False)])
def test_camera_without_version_inquiry_still_starts(rig: Rig) -> None:
    assert rig.client.version is None
    assert any("version" in w for w in rig.client.stats.startup_warnings)
