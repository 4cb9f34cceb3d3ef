"""Recovery from every injected fault, over a real pty and over TCP.

Invariant checked throughout: every scan the client delivers equals the fake's (deterministic) room,
so a corrupted frame is never delivered; corrupted replies are counted; streaming resumes on its own.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from drivers.hokuyo_scip.client import ConnectionState, LaserScan, Utm30lxClient
from drivers.hokuyo_scip.codec import StatusMeaning
from drivers.hokuyo_scip.errors import ScipDisconnectedError, ScipStatusError
from hil_fakes.transport import DeviceServer
from hil_fakes.utm30lx import Utm30lxModel

from .helpers import fast_config, room_truth_mm, start_fake, wait_until


@pytest.fixture(params=["pty", "tcp"])
def fake(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[DeviceServer]:
    server = start_fake(request.param, tmp_path)
    yield server
    server.stop()


@pytest.fixture
def streaming(fake: DeviceServer) -> Iterator[Utm30lxClient]:
    c = Utm30lxClient(fake.address, fast_config()).open()
    c.start_stream()
    c.next_scan(timeout_s=5.0)
    yield c
    c.close()


def model_of(server: DeviceServer) -> Utm30lxModel:
    assert isinstance(server.model, Utm30lxModel)
    return server.model


def collect(client: Utm30lxClient, seconds: float) -> list[LaserScan]:
    out = []
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        s = client.latest_scan()
        if s is not None:
            out.append(s)
        time.sleep(0.005)
    return out


def assert_all_true(scans: list[LaserScan], server: DeviceServer) -> None:
    truth = room_truth_mm(model_of(server)).tolist()
    for s in scans:
        assert s.raw_mm.tolist() == truth, f"scan {s.seq} differs from what the fake measured"


def resumes(client: Utm30lxClient, server: DeviceServer, timeout_s: float = 15.0) -> None:
    """Frames keep coming: at least 5 more true scans within ``timeout_s``."""
    start = client.stats.frames
    assert wait_until(lambda: client.stats.frames >= start + 5, timeout_s), client.stats
    s = client.next_scan(timeout_s=5.0)
    assert_all_true([s], server)


def test_corrupted_bytes_are_counted_and_never_delivered(streaming: Utm30lxClient, fake: DeviceServer) -> None:
    fake.faults.corrupt(3)
    scans = collect(streaming, 0.5)
    assert wait_until(lambda: streaming.stats.corrupted_frames >= 3, 5.0), streaming.stats
    scans += collect(streaming, 0.2)
    assert_all_true(scans, fake)
    resumes(streaming, fake)


@pytest.mark.parametrize("where", ["status", "timestamp", "data"])
def test_each_checksum_fault_is_caught(streaming: Utm30lxClient, fake: DeviceServer, where: str) -> None:
    model_of(fake).inject_checksum_error(where, frames=2)
    assert wait_until(lambda: streaming.stats.corrupted_frames >= 2, 5.0), streaming.stats
    assert_all_true(collect(streaming, 0.2), fake)
    resumes(streaming, fake)


def test_split_writes_still_decode(streaming: Utm30lxClient, fake: DeviceServer) -> None:
    fake.faults.split(chunk_bytes=7, delay_s=0.0002, writes=4)
    scans = collect(streaming, 0.6)
    assert_all_true(scans, fake)
    assert streaming.stats.corrupted_frames == 0
    resumes(streaming, fake)


def test_dropped_bytes_lose_one_frame_only(streaming: Utm30lxClient, fake: DeviceServer) -> None:
    fake.faults.drop(100)
    assert wait_until(lambda: streaming.stats.corrupted_frames >= 1, 5.0), streaming.stats
    assert_all_true(collect(streaming, 0.3), fake)
    resumes(streaming, fake)


def test_junk_between_frames_is_skipped(streaming: Utm30lxClient, fake: DeviceServer) -> None:
    fake.faults.junk(b"\x00\xffjunk\x13")
    assert wait_until(lambda: streaming.stats.garbage_events + streaming.stats.corrupted_frames >= 1, 5.0)
    assert_all_true(collect(streaming, 0.3), fake)
    resumes(streaming, fake)


def test_short_stall_resumes_without_reconnect(streaming: Utm30lxClient, fake: DeviceServer) -> None:
    fake.faults.stall(0.25)  # below 4 windows of 0.2 s
    time.sleep(0.3)
    resumes(streaming, fake)
    assert streaming.stats.reconnects == 0


def test_long_stall_reconnects_and_resumes(fake: DeviceServer) -> None:
    with Utm30lxClient(fake.address, fast_config(frame_timeout_s=0.1, reply_timeout_s=0.5)) as streaming:
        streaming.start_stream()
        streaming.next_scan(timeout_s=5.0)
        _long_stall(streaming, fake)


def _long_stall(streaming: Utm30lxClient, fake: DeviceServer) -> None:
    fake.faults.stall(0.8)  # beyond 4 windows of 0.1 s
    assert wait_until(lambda: streaming.stats.reconnects >= 1, 20.0), streaming.stats
    assert streaming.stats.silent_windows >= 4
    resumes(streaming, fake)
    assert streaming.state is ConnectionState.STREAMING
    assert isinstance(streaming.last_error, TimeoutError)


def test_disconnect_and_replug(streaming: Utm30lxClient, fake: DeviceServer) -> None:
    before = streaming.stats.frames
    fake.faults.disconnect()  # a pty replug keeps the symlink; TCP drops the connection
    assert wait_until(lambda: streaming.stats.reconnects >= 1, 20.0), streaming.stats
    resumes(streaming, fake)
    assert streaming.stats.frames > before
    assert streaming.state is ConnectionState.STREAMING


def test_power_cycle_behind_a_replug_is_a_clock_reset(streaming: Utm30lxClient, fake: DeviceServer) -> None:
    first = streaming.next_scan(timeout_s=5.0)
    model_of(fake).power_cycle(fake.clock())
    fake.faults.disconnect()
    assert wait_until(lambda: streaming.stats.reconnects >= 1, 20.0), streaming.stats
    resumes(streaming, fake)
    later = streaming.next_scan(timeout_s=5.0)
    assert later.device_epoch > first.device_epoch
    assert later.device_stamp_raw_ms < first.device_stamp_raw_ms
    assert later.stamp_from_time_sync  # re-synced after the reconnect
    truth = model_of(fake).host_time_of_device_ms(later.device_stamp_raw_ms)
    assert abs(later.stamp_s - truth) < 0.05


def test_error_status_frames_are_counted_and_streaming_goes_on(streaming: Utm30lxClient, fake: DeviceServer) -> None:
    model_of(fake).inject_frame_status("50", frames=3)
    assert wait_until(lambda: streaming.stats.status_errors >= 3, 5.0), streaming.stats
    assert streaming.stats.last_status == "50"
    assert_all_true(collect(streaming, 0.2), fake)
    resumes(streaming, fake)


def test_command_error_status_raises_typed(fake: DeviceServer) -> None:
    with Utm30lxClient(fake.address, fast_config()) as c:
        model_of(fake).inject_status("BM", "01")
        with pytest.raises(ScipStatusError) as info:
            c.laser_on()
        assert info.value.code == "01" and info.value.command == "BM"
        model_of(fake).inject_status("GD", "0E")
        with pytest.raises(ScipStatusError) as info2:
            c.get_scan()
        assert info2.value.code == "0E"
        from drivers.hokuyo_scip.codec import status_for

        assert status_for("BM", "01").meaning is StatusMeaning.LASER_FAULT
        assert c.get_scan().ranges_m.size == 1081  # and it works again


def test_stream_start_refused_with_status(fake: DeviceServer) -> None:
    with Utm30lxClient(fake.address, fast_config()) as c:
        model_of(fake).inject_status("MD", "0B")
        with pytest.raises(ScipStatusError):
            c.start_stream()
        assert not c.streaming and c.state is ConnectionState.IDLE
        c.start_stream()
        c.next_scan(timeout_s=5.0)
        c.stop_stream()


def test_open_when_a_previous_client_left_it_streaming(fake: DeviceServer) -> None:
    model = model_of(fake)
    model.leave_streaming("ME0000108001000", now_s=fake.clock())
    assert wait_until(lambda: model.frames_sent >= 3, 5.0)
    with Utm30lxClient(fake.address, fast_config()) as c:
        assert not model.streaming
        assert c.info.version.serial == "00903971"
        assert_all_true([c.get_scan()], fake)


def test_open_when_stuck_in_time_adjust_mode(fake: DeviceServer) -> None:
    model = model_of(fake)
    model.enter_time_mode()
    with Utm30lxClient(fake.address, fast_config()) as c:
        assert not model.time_mode
        assert c.clock_offset is not None
        assert_all_true([c.get_scan()], fake)
    seen = model.commands_seen
    assert seen.index("TM2") < seen.index("VV")


def test_unplug_while_idle_reconnects_on_the_next_command(fake: DeviceServer) -> None:
    with Utm30lxClient(fake.address, fast_config()) as c:
        fake.faults.disconnect()
        time.sleep(0.1)
        assert_all_true([c.get_scan()], fake)
        assert c.stats.reconnects >= 1


def test_reader_gives_up_and_surfaces_the_error(tmp_path: Path) -> None:
    server = start_fake("pty", tmp_path)
    c = Utm30lxClient(server.address, fast_config(max_reconnect_attempts=2)).open()
    try:
        c.start_stream()
        c.next_scan(timeout_s=5.0)
        server.stop()  # the device is gone for good (the link is removed)
        assert wait_until(lambda: c.state is ConnectionState.FAILED, 20.0), c.stats
        with pytest.raises(ScipDisconnectedError):
            while True:
                c.next_scan(timeout_s=5.0)
        assert isinstance(c.last_error, ScipDisconnectedError)
    finally:
        c.close()
    assert c.state is ConnectionState.CLOSED


def test_commands_after_the_reader_gave_up_reopen_when_the_device_is_back(tmp_path: Path) -> None:
    link = tmp_path / "hokuyo"
    server = start_fake("pty", tmp_path)
    c = Utm30lxClient(str(link), fast_config(max_reconnect_attempts=1)).open()
    try:
        c.start_stream()
        c.next_scan(timeout_s=5.0)
        server.stop()
        assert wait_until(lambda: c.state is ConnectionState.FAILED, 20.0), c.stats
        server = start_fake("pty", tmp_path)  # plugged in again under the same name
        c.stop_stream()  # the stream is over; nothing to stop on the device side
        assert_all_true([c.get_scan()], server)
        assert c.state is ConnectionState.IDLE
    finally:
        c.close()
        server.stop()
