"""Conformance: the client against the fake UTM-30LX over a real pty and over loopback TCP.

No rate or timing assertions (shared, loaded machine): frame counts are loose lower bounds and
every wait has a generous timeout.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from drivers.hokuyo_scip.client import ConnectionState, LaserScan, Utm30lxClient
from drivers.hokuyo_scip.errors import ScipConfigError, ScipDisconnectedError, ScipStateError
from hil_fakes.transport import DeviceServer
from hil_fakes.utm30lx import Utm30lxConfig, Utm30lxModel

from .helpers import fast_config, room_truth_mm, start_fake, wait_until


@pytest.fixture(params=["pty", "tcp"])
def fake(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[DeviceServer]:
    server = start_fake(request.param, tmp_path)
    yield server
    server.stop()


@pytest.fixture
def client(fake: DeviceServer) -> Iterator[Utm30lxClient]:
    c = Utm30lxClient(fake.address, fast_config()).open()
    yield c
    c.close()


def model_of(server: DeviceServer) -> Utm30lxModel:
    assert isinstance(server.model, Utm30lxModel)
    return server.model


def assert_room_scan(scan: LaserScan, model: Utm30lxModel) -> None:
    truth = room_truth_mm(model)
    assert scan.raw_mm.tolist() == truth.tolist()
    assert np.allclose(scan.ranges_m, truth / 1000.0)


def test_handshake_reads_typed_info(client: Utm30lxClient, fake: DeviceServer) -> None:
    info = client.info
    assert info.version.serial == "00903971"
    assert info.version.firmware == "P.1.05(17/Apr./2009)"
    assert info.params.n_steps == 1081 and info.params.afrt == 540 and info.params.scan_rpm == 2400
    assert info.values["PP"]["DMIN"] == "23"
    assert info.state.model.startswith("UTM-30LX")
    assert client.state is ConnectionState.IDLE
    # the handshake ended with the sensor idle: QT sent, TM mode left after the clock sync
    model = model_of(fake)
    assert "QT" in model.commands_seen and model.commands_seen[-1] == "TM2"
    assert not model.streaming and not model.time_mode
    off = client.clock_offset
    assert off is not None and off.samples == 3


def test_single_scan_gd(client: Utm30lxClient, fake: DeviceServer) -> None:
    scan = client.get_scan()
    assert_room_scan(scan, model_of(fake))
    assert scan.intensities is None
    assert scan.bearings_rad.size == 1081
    assert scan.bearings_rad[0] == pytest.approx(-3 * math.pi / 4)
    assert scan.bearings_rad[540] == pytest.approx(0.0)
    assert scan.bearings_rad[-1] == pytest.approx(3 * math.pi / 4)
    assert scan.beam_dt_s == pytest.approx(0.025 / 1440)
    assert scan.stamp_from_time_sync
    assert "BM" in model_of(fake).commands_seen and model_of(fake).commands_seen[-1] == "GD0000108001"


def test_single_scan_ge_with_intensities(client: Utm30lxClient) -> None:
    scan = client.get_scan(intensity=True)
    assert scan.intensities is not None and scan.intensities.shape == (1081,)
    assert (scan.intensities > 0).all()


def test_md_streaming_two_seconds(client: Utm30lxClient, fake: DeviceServer) -> None:
    model = model_of(fake)
    client.start_stream()
    assert client.state is ConnectionState.STREAMING
    scans: list[LaserScan] = []
    t_end = time.monotonic() + 2.2
    while time.monotonic() < t_end:
        scans.append(client.next_scan(timeout_s=5.0))
    client.stop_stream()
    assert client.state is ConnectionState.IDLE and not model.streaming
    assert len(scans) >= 20  # 40 Hz nominal; loose under load
    for s in scans:
        assert_room_scan(s, model)
    seqs = [s.seq for s in scans]
    assert seqs == sorted(seqs) and len(set(seqs)) == len(seqs)
    device = [s.device_stamp_ms for s in scans]
    steps = np.diff(device)
    assert (steps > 0).all()
    # scans are 25 ms apart on the fake's clock (floor to whole ms: 24..26 per scan skipped or not)
    assert all(round(d / 25.0) >= 1 and abs(d - 25.0 * round(d / 25.0)) <= 1 for d in steps)
    hosts = [s.host_stamp_s for s in scans]
    assert hosts == sorted(hosts)
    for s in scans:
        assert s.stamp_from_time_sync
        assert s.stamp_s < s.host_stamp_s  # step 0 was before the frame arrived
    st = client.stats
    assert st.corrupted_frames == 0 and st.reconnects == 0
    assert st.frames >= len(scans)


def test_me_streaming_has_intensities(client: Utm30lxClient, fake: DeviceServer) -> None:
    client.start_stream(intensity=True)
    scans = [client.next_scan(timeout_s=5.0) for _ in range(5)]
    client.stop_stream()
    for s in scans:
        assert s.intensities is not None and s.intensities.shape == (1081,)
        assert_room_scan(s, model_of(fake))
    assert model_of(fake).commands_seen[-2] == "ME0000108001000"


def test_time_sync_matches_the_fake_clock(client: Utm30lxClient, fake: DeviceServer) -> None:
    model = model_of(fake)
    offset = client.sync_time(rounds=5)
    assert offset.samples == 5 and offset.round_trip_s >= 0
    client.start_stream()
    scans = [client.next_scan(timeout_s=5.0) for _ in range(3)]
    client.stop_stream()
    for s in scans:
        truth = model.host_time_of_device_ms(s.device_stamp_raw_ms)
        # the offset is good to the round trip (sub-ms here) plus 1 ms of counter resolution;
        # the bound is loose for a loaded machine
        assert abs(s.stamp_s - truth) < 0.05


def test_finite_count_stream_ends_by_itself(client: Utm30lxClient, fake: DeviceServer) -> None:
    client.start_stream(count=3)
    scans = [client.next_scan(timeout_s=5.0) for _ in range(3)]
    assert [s.remaining for s in scans] == [2, 1, 0]
    assert wait_until(lambda: not client.streaming, 5.0)
    assert client.state is ConnectionState.IDLE
    assert not model_of(fake).laser_on  # the laser goes off after a finite run
    client.stop_stream()
    assert_room_scan(client.get_scan(), model_of(fake))


def test_commands_while_streaming_are_refused(client: Utm30lxClient) -> None:
    client.start_stream()
    with pytest.raises(ScipStateError):
        client.get_scan()
    with pytest.raises(ScipStateError):
        client.sync_time()
    with pytest.raises(ScipStateError):
        client.start_stream()
    client.stop_stream()


def test_window_and_cluster_from_config(fake: DeviceServer) -> None:
    with Utm30lxClient(fake.address, fast_config(start_step=100, end_step=980, cluster=4)) as c:
        scan = c.get_scan()
    assert scan.ranges_m.size == -(-(980 - 100 + 1) // 4)
    assert scan.bearings_rad[0] == pytest.approx((100 - 540) * 2 * math.pi / 1440)
    assert scan.bearings_rad[1] - scan.bearings_rad[0] == pytest.approx(4 * 2 * math.pi / 1440)
    assert scan.beam_dt_s == pytest.approx(4 * 0.025 / 1440)
    with Utm30lxClient(fake.address, fast_config(end_step=1100)) as c, pytest.raises(ScipConfigError):
        c.get_scan()


def test_timestamp_wrap_is_unwrapped(tmp_path: Path) -> None:
    model = Utm30lxModel(Utm30lxConfig(initial_time_ms=(1 << 24) - 400))
    server = start_fake("pty", tmp_path, model)
    try:
        with Utm30lxClient(server.address, fast_config()) as c:
            c.start_stream()
            scans = [c.next_scan(timeout_s=5.0) for _ in range(30)]
            c.stop_stream()
            stats = c.stats
    finally:
        server.stop()
    raws = [s.device_stamp_raw_ms for s in scans]
    assert min(raws) < 1000 and max(raws) > (1 << 24) - 1000  # the counter wrapped inside the run
    unwrapped = [s.device_stamp_ms for s in scans]
    assert all(b > a for a, b in zip(unwrapped, unwrapped[1:]))
    assert max(unwrapped) > 1 << 24
    assert stats.time_resets == 0
    assert all(s.device_epoch == scans[0].device_epoch and s.stamp_from_time_sync for s in scans)


def test_reset_sensor_starts_a_new_clock_epoch(client: Utm30lxClient) -> None:
    before = client.get_scan()
    client.reset_sensor()
    assert client.clock_offset is None
    after = client.get_scan()
    assert after.device_epoch > before.device_epoch
    assert after.device_stamp_raw_ms < before.device_stamp_raw_ms
    assert not after.stamp_from_time_sync
    client.sync_time(rounds=3)
    assert client.get_scan().stamp_from_time_sync


def test_exclusive_open_of_the_pty(tmp_path: Path) -> None:
    server = start_fake("pty", tmp_path)
    try:
        with Utm30lxClient(server.address, fast_config()) as first:
            with pytest.raises(ScipDisconnectedError):
                Utm30lxClient(server.address, fast_config()).open()
            assert first.get_scan().ranges_m.size == 1081
    finally:
        server.stop()


def test_open_of_a_missing_device_is_a_typed_error(tmp_path: Path) -> None:
    with pytest.raises(ScipDisconnectedError):
        Utm30lxClient(str(tmp_path / "nothing"), fast_config()).open()
    with pytest.raises(ScipDisconnectedError):
        Utm30lxClient("socket://127.0.0.1:1", fast_config()).open()


def test_old_firmware_ii_checksum_quirk_is_accepted_and_flagged(tmp_path: Path,
                                                                caplog: pytest.LogCaptureFixture) -> None:
    model = Utm30lxModel(Utm30lxConfig(ii_sum_before_arrow=True))
    server = start_fake("pty", tmp_path, model)
    try:
        with caplog.at_level("WARNING"), Utm30lxClient(server.address, fast_config()) as c:
            assert c.info.checksum_fallback_keys == ("SCSP",)
            assert c.info.state.motor_speed.startswith("Initial(2400[rpm])<-")
    finally:
        server.stop()
    assert any("before '<-'" in r.getMessage() for r in caplog.records)


def test_first_frame_read_with_the_acknowledgement_is_delivered(tmp_path: Path) -> None:
    # With a 50 ms reply latency the first frame is queued right behind the MD acknowledgement, so
    # both usually arrive in one read; that frame must be delivered, not skipped as a stray reply.
    model = Utm30lxModel(Utm30lxConfig(reply_latency_s=0.05))
    server = start_fake("pty", tmp_path, model)
    try:
        with Utm30lxClient(server.address, fast_config()) as c:
            strays = c.stats.stray_replies
            c.start_stream()
            first = c.next_scan(timeout_s=5.0)
            assert c.stats.stray_replies == strays  # (frames in flight before the QT echo are strays)
            assert first.seq == 1
            c.stop_stream()
    finally:
        server.stop()


def test_stamp_is_the_time_of_the_first_beam_of_the_window(fake: DeviceServer) -> None:
    with Utm30lxClient(fake.address, fast_config(start_step=720, end_step=1080)) as c:
        c.start_stream()
        scan = c.next_scan(timeout_s=5.0)
        c.stop_stream()
        offset = c.clock_offset
    assert offset is not None and scan.stamp_from_time_sync
    step0_s = scan.device_stamp_ms / 1000.0 + offset.offset_s  # the counter is latched at step 0
    assert scan.stamp_s - step0_s == pytest.approx(720 * 0.025 / 1440, abs=1e-9)
    truth = model_of(fake).host_time_of_device_ms(scan.device_stamp_raw_ms)
    assert abs(step0_s - truth) < 0.05


def test_clock_drift_is_followed_while_streaming(tmp_path: Path) -> None:
    # 1 % drift, exaggerated so 3 s of streaming separate tracked (few ms) from untracked (~30 ms) stamps.
    # On the wall clock a busy machine delays frames by a varying amount, so this checks what holds
    # however slow the machine: the correction has the drift's sign and brings the stamps closer to the
    # truth than the TM offset alone; its accuracy is checked on simulated arrival times (test_timebase.py).
    model = Utm30lxModel(Utm30lxConfig(clock_drift_ppm=10_000.0))
    server = start_fake("pty", tmp_path, model)
    try:
        with Utm30lxClient(server.address, fast_config(drift_window_s=0.5, drift_min_frames=5)) as c:
            c.start_stream()
            end = time.monotonic() + 3.0
            last = c.next_scan(timeout_s=5.0)
            while time.monotonic() < end:
                last = c.next_scan(timeout_s=5.0)
            c.stop_stream()
            offset = c.clock_offset
            assert offset is not None
            assert c.drift_correction_s < 0.0  # the device clock runs fast: the offset shrinks
        truth = model.host_time_of_device_ms(last.device_stamp_raw_ms)
        untracked = last.device_stamp_ms / 1000.0 + offset.offset_s  # what the TM offset alone gives
        assert abs(last.stamp_s - truth) < abs(untracked - truth)
    finally:
        server.stop()


def test_rep117_ranges_give_each_invalid_reading_its_ros_meaning() -> None:
    """+inf: nothing in range (code 1) or beyond DMAX; -inf: too close (code 2); NaN: codes 3-5 and
    other values below DMIN (fact sheet 1.7); valid readings unchanged."""
    raw = np.array([1, 2, 3, 4, 5, 12, 22, 23, 1500, 60000, 60001, 65533])
    ranges = raw * 0.001
    ranges[(raw < 23) | (raw > 60000)] = np.nan
    scan = LaserScan(ranges_m=ranges, raw_mm=raw, intensities=None, bearings_rad=np.zeros(len(raw)),
                     device_stamp_raw_ms=0, device_stamp_ms=0, device_epoch=0, host_stamp_s=0.0, stamp_s=0.0,
                     stamp_from_time_sync=False, beam_dt_s=0.0, seq=1, dmin_mm=23, dmax_mm=60000)
    out = scan.rep117_ranges_m()
    assert out[0] == math.inf and out[1] == -math.inf
    assert np.isnan(out[2:7]).all()
    assert out[7] == 0.023 and out[8] == 1.5 and out[9] == 60.0
    assert out[10] == math.inf and out[11] == math.inf
    assert np.isnan(scan.ranges_m[0])  # the driver's own ranges keep NaN for every invalid reading
