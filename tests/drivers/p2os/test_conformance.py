"""The ARCOS client against the fake Pioneer over a real pty and over loopback TCP.

No timed assertions: every wait is a bounded poll with a generous limit, and what is checked is
what happened (counters, poses, flags), not how fast.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from drivers.p2os.client import ArcosClient, ArcosClientConfig, ConnectionState
from drivers.p2os.errors import ArcosDisconnectedError, ArcosTimeoutError, HandshakeError
from drivers.p2os.odometry import OdometrySample
from hil_fakes.pioneer import FakePioneer, PioneerConfig, serve
from hil_fakes.transport import DeviceServer

TRANSPORTS = ["pty", "tcp"]


class Rig:
    def __init__(self, transport: str, tmp_path: Path, fake_config: PioneerConfig | None = None) -> None:
        self.fake = FakePioneer(fake_config or PioneerConfig())
        if transport == "tcp":
            self.server: DeviceServer = serve(self.fake, tcp="127.0.0.1:0")
        else:
            self.server = serve(self.fake, pty=True, link=str(tmp_path / "pioneer"))
        self.clients: list[ArcosClient] = []

    @property
    def url(self) -> str:
        return self.server.address

    def client(self, **kw: object) -> ArcosClient:
        kw.setdefault("url", self.url)
        kw.setdefault("sip_silence_timeout_s", 1.0)
        kw.setdefault("reconnect_initial_s", 0.1)
        kw.setdefault("reconnect_max_s", 0.5)
        kw.setdefault("buffer_capacity", 64)  # a test thread starved by load must not see drops
        c = ArcosClient(ArcosClientConfig(**kw))  # type: ignore[arg-type]
        self.clients.append(c)
        return c

    def close(self) -> None:
        for c in self.clients:
            c.close()
        self.server.stop()


@pytest.fixture(params=TRANSPORTS)
def transport(request: pytest.FixtureRequest) -> str:
    return str(request.param)


@pytest.fixture
def make_rig(transport: str, tmp_path: Path) -> Iterator[Callable[..., Rig]]:
    rigs: list[Rig] = []

    def make(**fake_kw: object) -> Rig:
        # 20 Hz SIPs keep the suite short; the streaming test asks for the real 10 Hz explicitly
        fake_kw.setdefault("sip_cycle_s", 0.05)
        # brisk but legal accelerations (below the CONFIGpac tops): the protocol, not the ramps, is under test
        fake_kw.setdefault("trans_accel_mmps2", 1500)
        fake_kw.setdefault("rot_accel_degps2", 300)
        rig = Rig(transport, tmp_path, PioneerConfig(**fake_kw))  # type: ignore[arg-type]
        rigs.append(rig)
        return rig

    yield make
    for rig in rigs:
        rig.close()


def wait_for(pred: Callable[[], bool], timeout_s: float = 10.0, step_s: float = 0.02) -> bool:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if pred():
            return True
        time.sleep(step_s)
    return pred()


def keep_alive_for(client: ArcosClient, seconds: float) -> None:
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        client.heartbeat()
        time.sleep(0.05)


def command_until(client: ArcosClient, v_mps: float, w_radps: float, pred: Callable[[], bool]) -> bool:
    """Keep commanding (as a control loop would, so the command timeout never fires) until ``pred``."""

    def step() -> bool:
        client.set_velocity(v_mps, w_radps)
        return pred()

    return wait_for(step, step_s=0.1)


def newest(client: ArcosClient) -> OdometrySample:
    assert wait_for(lambda: client.last_sample is not None, timeout_s=5.0)
    s = client.last_sample
    assert s is not None
    return s


# ---- handshake --------------------------------------------------------------------------------------


def test_handshake_identity_and_config(make_rig: Callable[..., Rig]) -> None:
    rig = make_rig(name="robbie", subclass="p3dx-sh", watchdog_s=1.5)
    c = rig.client()
    info = c.connect()
    assert (info.name, info.robot_class, info.subclass) == ("robbie", "Pioneer", "p3dx-sh")
    assert info.params.dist_conv_mm_per_count == 1.0
    assert info.config is not None
    assert info.config.values["watchdog_ms"] == 1500 and info.config.values["sip_cycle_ms"] == 50
    assert info.config.values["serial_number"] == "FAKE0001"
    assert c.state is ConnectionState.CONNECTED
    assert wait_for(lambda: c.last_sample is not None and c.last_sample.motors_enabled)
    assert c.stats.sync_restarts == 0 and c.stats.stale_sessions == 0


def test_motors_stay_disabled_when_not_asked(make_rig: Callable[..., Rig]) -> None:
    rig = make_rig()
    c = rig.client(enable_motors=False)
    c.connect()
    s = c.get_sample(5.0)
    assert not s.motors_enabled
    c.set_velocity(0.3, 0.0)
    keep_alive_for(c, 0.5)
    assert rig.fake.truth(time.monotonic())[3] == 0.0  # motion commands do nothing without ENABLE


def test_stale_open_session_is_closed_and_resynced(make_rig: Callable[..., Rig]) -> None:
    rig = make_rig(start_open=True)
    c = rig.client()
    info = c.connect()
    assert info.name == "fakebot"
    assert c.stats.stale_sessions >= 1
    assert rig.fake.stats.sessions_closed >= 1
    assert c.get_sample(5.0).rebaselined


def test_out_of_order_sync_echo_restarts_the_handshake(make_rig: Callable[..., Rig]) -> None:
    rig = make_rig()
    rig.fake.misorder_sync(1)
    c = rig.client()
    assert c.connect().subclass == "p3dx"
    assert c.stats.sync_restarts >= 1


def test_a_late_duplicate_echo_is_ignored(make_rig: Callable[..., Rig]) -> None:
    rig = make_rig()
    rig.fake.misorder_sync(1, skip=2)  # the SYNC2 reply comes back as an echo 0
    c = rig.client(sync_step_timeout_s=0.3)
    assert c.connect().subclass == "p3dx"
    assert c.stats.sync_duplicates == 1 and c.stats.sync_restarts == 1


def test_a_silent_port_gives_a_typed_timeout(make_rig: Callable[..., Rig]) -> None:
    rig = make_rig()
    rig.server.faults.stall(30.0)
    c = rig.client(sync_step_timeout_s=0.2, sync_attempts=2, stale_close_wait_s=0.05)
    with pytest.raises(ArcosTimeoutError):
        c.connect()
    assert c.state is ConnectionState.CLOSED


def test_endless_misorder_gives_a_handshake_error(make_rig: Callable[..., Rig]) -> None:
    rig = make_rig()
    rig.fake.misorder_sync(1000)
    c = rig.client(sync_step_timeout_s=0.3, sync_attempts=3)
    with pytest.raises(HandshakeError):
        c.connect()


# ---- streaming and driving ------------------------------------------------------------------------


def test_streaming_at_the_sip_cycle(make_rig: Callable[..., Rig]) -> None:
    rig = make_rig(sip_cycle_s=0.1)
    c = rig.client()
    c.connect()
    samples = []
    sent0 = None
    while len(samples) < 12:
        s = c.get_sample(5.0)
        if sent0 is None:
            sent0 = rig.fake.stats.sips_sent
        samples.append(s)
        c.heartbeat()
    seqs = [s.seq for s in samples]
    assert seqs == list(range(seqs[0], seqs[0] + 12))  # nothing dropped or reordered
    dts = sorted(b.stamp_s - a.stamp_s for a, b in zip(samples, samples[1:]))
    median = dts[len(dts) // 2]
    assert 0.05 < median < 0.2  # 10 Hz SIPs; loose bound (shared, loaded machine)
    assert c.samples.dropped == 0
    assert all(len(s.sonars) == 16 for s in samples)
    assert all(s.sonars[i].pose is not None for s in samples for i in range(16))
    assert samples[-1].battery_v == pytest.approx(12.5)


def test_scripted_drive_matches_ground_truth_through_all_wraps(make_rig: Callable[..., Rig], transport: str) -> None:
    heading_signed = transport == "tcp"  # AMRISim sends -2048..2047; cover 0..4095 on the pty
    rig = make_rig(
        start_x_counts=32500,
        start_y_counts=32700,
        start_th_units=3900,  # 342.8 deg: the drive turns through 360 (unsigned wrap) and 540 (signed wrap)
        heading_signed=heading_signed,
        trans_accel_mmps2=1500,
        rot_accel_top_degps2=600,
        rot_accel_degps2=600,
    )
    c = rig.client()
    c.connect()
    c.get_sample(5.0)
    script = [(0.8, 0.0, 0.4), (0.6, 2.5, 1.6), (-0.3, -0.5, 0.4), (0.0, 0.0, 0.0)]
    for v, w, seconds in script:
        end = time.monotonic() + seconds
        while True:
            c.set_velocity(v, w)
            if time.monotonic() >= end:
                break
            time.sleep(0.1)
    # wait until the robot is at rest and a SIP taken at rest has arrived
    assert wait_for(lambda: rig.fake.truth(time.monotonic())[3:] == (0.0, 0.0))
    keep_alive_for(c, 0.4)
    s = newest(c)
    x, y, th, _, _ = rig.fake.truth(time.monotonic())
    st = rig.fake.stats
    assert st.x_wraps >= 1 and st.y_wraps >= 1 and st.th_wraps >= 1, st
    assert rig.fake.plant.unicycle.distance_m > 1.0  # type: ignore[attr-defined]  # it really drove
    err = (s.x_m - x, s.y_m - y, math.degrees(math.remainder(s.theta_rad - th, 2 * math.pi)))
    assert abs(err[0]) <= 0.001 and abs(err[1]) <= 0.001, err
    assert abs(err[2]) <= 0.05, err
    assert c.decoder_stats.checksum_errors == 0


def test_vel2_and_stop(make_rig: Callable[..., Rig]) -> None:
    rig = make_rig()
    c = rig.client()
    c.connect()

    def vel2_step() -> bool:
        c.set_wheel_velocities(0.2, 0.2)
        return newest(c).v_mps > 0.15

    assert wait_for(vel2_step, step_s=0.1)
    assert rig.fake.setpoint == (200.0, 0.0)
    c.stop()
    assert wait_for(lambda: newest(c).v_mps == 0.0 and rig.fake.truth(time.monotonic())[3] == 0.0)


def test_e_stop_halts_at_once(make_rig: Callable[..., Rig]) -> None:
    rig = make_rig()
    c = rig.client()
    c.connect()
    assert command_until(c, 0.5, 0.0, lambda: newest(c).v_mps > 0.3)
    c.e_stop()
    assert wait_for(lambda: newest(c).estop_pressed)
    assert rig.fake.truth(time.monotonic())[3] == 0.0


def test_encoder_and_io_packets(make_rig: Callable[..., Rig]) -> None:
    rig = make_rig()
    c = rig.client()
    c.connect()
    c.request_encoder(True)
    c.request_io(1)
    assert wait_for(lambda: c.last_encoder is not None and c.last_io is not None)
    io = c.last_io
    assert io is not None and io.digital_in == b"\x00" and len(io.analog_raw) == 1
    c.request_encoder(False)
    assert c.stats.unexpected_packets == 0


def test_limits_and_seto(make_rig: Callable[..., Rig]) -> None:
    rig = make_rig(subclass="p3dx-sh")
    c = rig.client()
    c.connect()
    c.set_limits(max_v_mps=0.1, accel_mps2=0.5, decel_mps2=0.5, max_w_radps=1.0, rot_accel_radps2=2.0)
    assert command_until(c, 0.5, 0.0, lambda: rig.fake.truth(time.monotonic())[3] >= 0.1 - 1e-9)
    end = time.monotonic() + 0.5
    while time.monotonic() < end:
        c.set_velocity(0.5, 0.0)
        assert rig.fake.truth(time.monotonic())[3] == pytest.approx(0.1)  # SETV clamps VEL on the robot
        time.sleep(0.1)
    c.set_velocity(0.0, 0.0)
    assert wait_for(lambda: rig.fake.truth(time.monotonic())[3] == 0.0)
    keep_alive_for(c, 0.3)
    assert newest(c).x_m > 0.05
    c.reset_odometry()
    assert wait_for(lambda: newest(c).rebaselined and abs(newest(c).x_m) < 0.002)
    assert rig.fake.raw_odometry_pose() == pytest.approx((0.0, 0.0, 0.0), abs=1e-6)


# ---- watchdog, keep-alive, command timeout ---------------------------------------------------------


def test_firmware_watchdog_stops_the_robot_when_keepalives_cease(make_rig: Callable[..., Rig]) -> None:
    rig = make_rig(watchdog_s=0.6)
    c = rig.client(command_timeout_s=None, heartbeat_timeout_s=0.2, keepalive_interval_s=0.1)
    c.connect()
    c.set_velocity(0.2, 0.0)  # then the application "hangs": no heartbeat, no command
    assert wait_for(lambda: rig.fake.stats.watchdog_trips >= 1, timeout_s=10.0)
    assert wait_for(lambda: newest(c).v_mps == 0.0)
    assert c.stats.command_timeouts == 0
    sent = c.stats.keepalives_sent
    time.sleep(0.3)
    assert c.stats.keepalives_sent == sent  # nothing feeds the watchdog while the app is dead


def test_keepalive_feeds_the_watchdog_while_the_app_is_alive(make_rig: Callable[..., Rig]) -> None:
    rig = make_rig(watchdog_s=1.0)
    c = rig.client(command_timeout_s=None, heartbeat_timeout_s=0.3, keepalive_interval_s=0.1)
    c.connect()
    c.set_velocity(0.2, 0.0)
    keep_alive_for(c, 2.1)  # more than twice the watchdog without a motion command
    assert rig.fake.stats.watchdog_trips == 0
    assert c.stats.keepalives_sent >= 3
    assert newest(c).v_mps > 0.1


def test_keepalive_never_slower_than_a_quarter_of_the_watchdog(make_rig: Callable[..., Rig]) -> None:
    rig = make_rig(watchdog_s=0.8)
    c = rig.client(command_timeout_s=None, keepalive_interval_s=5.0, heartbeat_timeout_s=0.5)
    c.connect()
    assert c.keepalive_interval_s == pytest.approx(0.2)
    c.set_velocity(0.2, 0.0)
    keep_alive_for(c, 1.8)
    assert rig.fake.stats.watchdog_trips == 0


def test_command_timeout_commands_zero_velocity(make_rig: Callable[..., Rig]) -> None:
    rig = make_rig(watchdog_s=5.0)
    c = rig.client(command_timeout_s=0.3, heartbeat_timeout_s=1.0)
    c.connect()
    c.set_velocity(0.3, 0.2)
    assert wait_for(lambda: c.stats.command_timeouts == 1)
    assert wait_for(lambda: rig.fake.setpoint == (0.0, 0.0))
    # the fake saw our command and then the client's own zero velocity
    assert rig.fake.stats.commands[11] >= 2 and rig.fake.stats.commands[21] >= 2
    assert wait_for(lambda: rig.fake.truth(time.monotonic())[3] == 0.0)
    assert rig.fake.stats.watchdog_trips == 0
    assert c.stats.command_timeouts == 1


def test_close_stops_disables_and_closes(make_rig: Callable[..., Rig]) -> None:
    rig = make_rig()
    c = rig.client()
    c.connect()
    assert command_until(c, 0.2, 0.0, lambda: newest(c).v_mps > 0.1)
    c.close()
    assert c.state is ConnectionState.CLOSED
    assert c.close_confirmed is True
    assert wait_for(lambda: rig.fake.state == "sync0")
    assert not rig.fake.motors_enabled and rig.fake.setpoint == (0.0, 0.0)
    assert rig.fake.stats.sessions_closed == 1
    with pytest.raises(ArcosDisconnectedError):
        c.set_velocity(0.1, 0.0)
    # the port is free again: a second client connects without a stale session
    c2 = rig.client()
    c2.connect()
    assert c2.stats.stale_sessions == 0


# ---- injected faults ---------------------------------------------------------------------------------


def _connected(rig: Rig, **kw: object) -> ArcosClient:
    c = rig.client(**kw)
    c.connect()
    c.get_sample(5.0)
    return c


def _samples_keep_flowing(c: ArcosClient, n: int = 5) -> None:
    got = 0
    deadline = time.monotonic() + 15.0
    while got < n and time.monotonic() < deadline:
        try:
            c.get_sample(1.0)
            got += 1
        except (ArcosDisconnectedError, TimeoutError):
            pass
        c.heartbeat()
    assert got == n


def test_recovers_from_corrupted_frames(make_rig: Callable[..., Rig]) -> None:
    rig = make_rig()
    c = _connected(rig)
    rig.server.faults.corrupt(3)
    assert wait_for(lambda: c.stats.checksum_errors >= 3)
    _samples_keep_flowing(c)
    assert c.stats.reconnects == 0


def test_junk_before_sips_costs_no_sip(make_rig: Callable[..., Rig]) -> None:
    rig = make_rig()
    c = _connected(rig)
    rig.fake.junk_before_sips(every=2)
    seen: list[int] = []
    while len(seen) < 20:
        seen.append(c.get_sample(5.0).seq)
        c.heartbeat()
    rig.fake.junk_before_sips(0)
    assert seen == list(range(seen[0], seen[0] + 20))  # every SIP arrived despite the junk
    assert c.stats.checksum_errors >= 5
    # a junk header claiming 254 bytes swallows the next SIPs' bytes; rescanning must recover them all
    rig.server.faults.junk(b"\xfa\xfb\xfe\x00")
    more = [c.get_sample(5.0).seq for _ in range(10)]
    assert more == list(range(seen[-1] + 1, seen[-1] + 11))


def test_split_and_dropped_bytes(make_rig: Callable[..., Rig]) -> None:
    rig = make_rig()
    c = _connected(rig)
    rig.server.faults.split(chunk_bytes=3, delay_s=0.002, writes=5)
    _samples_keep_flowing(c, 5)
    rig.server.faults.drop(7)
    assert wait_for(lambda: c.stats.bad_frames >= 1 or c.decoder_stats.junk_bytes > 0)
    _samples_keep_flowing(c, 5)
    assert c.stats.reconnects == 0


def test_stall_longer_than_the_silence_timeout_reconnects(make_rig: Callable[..., Rig]) -> None:
    rig = make_rig()
    c = _connected(rig, sip_silence_timeout_s=0.5)
    rig.server.faults.stall(0.8)
    assert wait_for(lambda: c.stats.reconnects >= 1, timeout_s=20.0)
    assert c.state is ConnectionState.CONNECTED
    _samples_keep_flowing(c)
    assert any("no SIP" in e for e in c.stats.errors)


def test_disconnect_reconnects(make_rig: Callable[..., Rig]) -> None:
    rig = make_rig()
    c = _connected(rig)
    before = newest(c)
    rig.server.faults.disconnect()
    assert wait_for(lambda: c.stats.reconnects >= 1, timeout_s=20.0)
    _samples_keep_flowing(c)
    after = newest(c)
    assert (after.x_m, after.y_m) == pytest.approx((before.x_m, before.y_m), abs=0.001)


def test_controller_reset_reconnects_and_keeps_the_pose(make_rig: Callable[..., Rig]) -> None:
    rig = make_rig(subclass="p3dx-sh")
    c = _connected(rig)
    assert command_until(c, 0.3, 0.0, lambda: newest(c).x_m > 0.05)
    c.set_velocity(0.0, 0.0)
    assert wait_for(lambda: rig.fake.truth(time.monotonic())[3] == 0.0)
    keep_alive_for(c, 0.3)
    before = newest(c)
    rig.fake.send_reset_packet()
    assert wait_for(lambda: c.stats.controller_resets >= 1 and c.stats.reconnects >= 1, timeout_s=20.0)
    _samples_keep_flowing(c)
    after = newest(c)
    assert (after.x_m, after.y_m) == pytest.approx((before.x_m, before.y_m), abs=1e-3)
    assert after.theta_rad == pytest.approx(before.theta_rad, abs=1e-3)
    # and it drives on from there
    x, _, _, _, _ = rig.fake.truth(time.monotonic())
    assert after.x_m == pytest.approx(x, abs=0.001)


def test_no_reconnect_surfaces_the_error(make_rig: Callable[..., Rig]) -> None:
    rig = make_rig()
    c = _connected(rig, reconnect=False)
    rig.fake.send_reset_packet()
    assert wait_for(lambda: c.state is ConnectionState.LOST)
    c.samples.clear()
    with pytest.raises(ArcosDisconnectedError):
        c.get_sample(1.0)
    assert c.last_error is not None
    c.connect()  # the caller may try again explicitly
    assert c.get_sample(5.0).rebaselined


def test_hostbaud_switch_on_a_tty(transport: str, make_rig: Callable[..., Rig]) -> None:
    if transport != "pty":
        pytest.skip("HOSTBAUD applies to serial ports only")
    rig = make_rig()
    c = _connected(rig, switch_baudrate=38400)
    assert c.info.baudrate == 38400
    assert rig.fake.host_baud == 38400
    assert c.stats.baud_fallbacks == 0
    _samples_keep_flowing(c)


def test_hostbaud_falls_back_when_the_controller_does_not_follow(transport: str, make_rig: Callable[..., Rig]) -> None:
    if transport != "pty":
        pytest.skip("HOSTBAUD applies to serial ports only")
    rig = make_rig(hostbaud_supported=False)  # the pty carries the rates: a mismatch garbles the line
    c = _connected(rig, switch_baudrate=38400, sip_silence_timeout_s=2.0)
    assert c.stats.baud_fallbacks == 1
    assert c.info.baudrate == 9600 and rig.fake.host_baud == 9600
    assert rig.fake.garbled_out_bytes > 0  # the fallback really met an unreadable line
    _samples_keep_flowing(c)


def test_baud_hunting_finds_the_controller_rate(transport: str, make_rig: Callable[..., Rig]) -> None:
    if transport != "pty":
        pytest.skip("baud rates apply to serial ports only")
    rig = make_rig(host_baud=38400)  # FLASH HostBaud changed from the 9600 default
    silent = rig.client(sync_step_timeout_s=0.2, sync_attempts=2, stale_close_wait_s=0.05, reconnect=False)
    with pytest.raises(ArcosTimeoutError):
        silent.connect()
    c = _connected(rig, sync_step_timeout_s=0.3, sync_attempts=2, baud_candidates=(19200, 38400, 115200))
    assert c.info.baudrate == 38400 and c.stats.baud_hunts == 2
    assert c.info.config is not None and c.info.config.values["host_baud"] == 2
    _samples_keep_flowing(c)
