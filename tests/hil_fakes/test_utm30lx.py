"""The fake UTM-30LX against the real recording, the SCIP rules, and urg_library's wire sequences.

The fake is driven directly (no transport) where exact bytes and times matter, and over a real pty
and TCP for the sequences Hokuyo's C library samples send (the samples themselves are not available
here; see docs/scanner.md).
"""

from __future__ import annotations

import os
import select
import socket
import time
import tty
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from drivers.hokuyo_scip.codec import ScanFrame, ScipDecoder, StateReply, StatusReply, TimeReply, VersionReply
from hil_fakes.transport import DeviceServer, PtyEndpoint, TcpEndpoint
from hil_fakes.utm30lx import FixedRoom, Utm30lxConfig, Utm30lxModel, data_block, encode, scip_sum
from tests.drivers.hokuyo_scip.helpers import load_session, sensor_bytes


class Driven:
    """A model driven by hand: explicit clock, output collected reply by reply. The link is instant
    (a reply is out when ``send`` returns) unless ``paced``; the link's pace has tests of its own."""

    def __init__(self, config: Utm30lxConfig | None = None, t0: float = 100.0, paced: bool = False) -> None:
        config = config or Utm30lxConfig()
        self.model = Utm30lxModel(config if paced else replace(config, link_bytes_per_s=0.0))
        self.out = bytearray()
        self.model.attach(self.out.extend)
        self.t = t0
        self.model.poll(t0)

    def send(self, line: bytes, dt: float = 0.0) -> bytes:
        self.t += dt
        start = len(self.out)
        self.model.on_bytes(line + b"\n", self.t)
        return bytes(self.out[start:])

    def advance(self, seconds: float, step: float = 0.001) -> bytes:
        start = len(self.out)
        end = self.t + seconds
        while self.t < end:
            self.t = min(end, self.t + step)
            self.model.poll(self.t)
        return bytes(self.out[start:])


def replies(raw: bytes) -> list[bytes]:
    parts = raw.split(b"\n\n")
    return [p + b"\n\n" for p in parts[:-1]]


# ------------------------------------------------------------------ against the recording


@pytest.fixture(scope="module")
def recorded(shared_data: Path) -> list[tuple[float, str, bytes]]:
    return load_session(shared_data, "example_utm_30lx")


def _recorded_requests(records: list[tuple[float, str, bytes]]) -> list[tuple[float, bytes]]:
    """(time of the LF, request line) in order."""
    out: list[tuple[float, bytes]] = []
    pending = b""
    for t, direction, payload in records:
        if direction != "host_to_sensor":
            continue
        pending += payload
        while b"\n" in pending:
            line, pending = pending.split(b"\n", 1)
            out.append((t, line))
    return out


def test_replies_match_the_recording_byte_for_byte(recorded: list[tuple[float, str, bytes]]) -> None:
    requests = _recorded_requests(recorded)
    assert [r for _, r in requests] == [b"VV", b"VV", b"PP", b"II", b"BM", b"CR00", b"VV", b"PP", b"II",
                                        b"ME0000108001101"]
    real = replies(sensor_bytes(recorded))
    fake = Driven(t0=requests[0][0])
    got: list[bytes] = []
    for t, line in requests[:-1]:
        fake.advance(t - fake.t)
        got.extend(replies(fake.send(line)))
    assert len(got) == 9
    for i, (line, mine, theirs) in enumerate(zip([r for _, r in requests], got, real)):
        if line == b"II":
            strip = [x for x in mine.split(b"\n") if not x.startswith(b"TIME:")]
            strip_real = [x for x in theirs.split(b"\n") if not x.startswith(b"TIME:")]
            assert strip == strip_real, f"II reply {i} differs beyond TIME"
        else:
            assert mine == theirs, f"reply {i} to {line!r} differs"
    # II TIME is the fake's own 24-bit counter: it advanced as much as the host clock between the two II
    times = [int(x[5:11], 16) for r in got for x in r.split(b"\n") if x.startswith(b"TIME:")]
    host_gap_ms = (requests[8][0] - requests[3][0]) * 1000
    assert abs((times[1] - times[0]) - host_gap_ms) <= 2
    assert times[0] == 4821456 + int((requests[3][0] - requests[0][0]) * 1000)


def test_me_frame_layout_matches_the_recording(recorded: list[tuple[float, str, bytes]]) -> None:
    real = replies(sensor_bytes(recorded))
    fake = Driven()
    ack = fake.send(b"ME0000108001101")
    assert ack == real[9] == b"ME0000108001101\n00P\n\n"
    frame = fake.advance(0.06)
    assert len(replies(frame)) == 1
    mine, theirs = frame.split(b"\n"), real[10].split(b"\n")
    assert len(frame) == len(real[10]) == 6717
    assert mine[:2] == theirs[:2] == [b"ME0000108001100", b"99b"]
    assert [len(x) for x in mine] == [len(x) for x in theirs]  # 102 data lines: 101 x 65 + 23
    assert fake.advance(0.1) == b""  # count 01: one frame, then the stream ends
    assert not fake.model.streaming and not fake.model.laser_on


# ------------------------------------------------------------------ scans on the fake's own clock


def test_frames_every_25_ms_with_step0_stamps_computed_once() -> None:
    fake = Driven(Utm30lxConfig(initial_time_ms=1000))
    t_ack = fake.t
    fake.send(b"MD0000108001000")
    events = ScipDecoder().feed(fake.advance(0.5))
    frames = [e for e in events if isinstance(e, ScanFrame)]
    assert len(events) == len(frames) == 20  # 0.5 s / 25 ms, no decode error: every sum matches its stamp
    stamps = [f.timestamp_ms for f in frames]
    assert np.all(np.diff(stamps) == 25)
    assert stamps[0] >= 1000 + int((t_ack - 100.0) * 1000)
    assert all(f.remaining == 0 for f in frames)
    truth = np.round(FixedRoom().sweep(0, (np.arange(1081) - 540) * 2 * np.pi / 1440, 0)[0] * 1000)
    assert frames[0].distances.tolist() == truth.astype(int).tolist()


def test_a_model_polled_late_counts_the_scans_it_sent_late_or_skipped() -> None:
    """A real-time fake on a host too busy to poll it on time: what it sends late is counted, so a run
    can tell a starved simulation from the sensor's behaviour."""
    fake = Driven()
    fake.send(b"MD0000108001000")
    fake.advance(0.5)
    assert fake.model.scans_late == 0 and fake.model.frames_sent == 20  # polled every millisecond
    sent = fake.model.frames_sent
    fake.advance(0.1, step=0.1)  # one poll after 0.1 s: four scans at once, three of them a period late
    assert fake.model.frames_sent - sent == 4 and fake.model.scans_late == 3
    fake.advance(1.0, step=1.0)  # 40 scans due: the last 8 are sent, 32 skipped, 7 of the 8 late
    assert fake.model.scans_late == 3 + 32 + 7
    every_other = Driven()
    every_other.send(b"MD0000108001100")  # interval 1: the scans in between are not the stream's
    every_other.advance(0.2, step=0.2)  # 8 scans due at once, 4 of them the stream's, all a period late
    assert every_other.model.frames_sent == 4 and every_other.model.scans_late == 4
    every_other.advance(1.0, step=1.0)  # 40 due: 32 skipped (16 the stream's), 8 measured (4 sent, late)
    assert every_other.model.scans_late == 4 + 16 + 4


def test_interval_and_finite_count() -> None:
    fake = Driven()
    fake.send(b"MD0000108001103")
    frames = [e for e in ScipDecoder().feed(fake.advance(0.4)) if isinstance(e, ScanFrame)]
    assert [f.remaining for f in frames] == [2, 1, 0]
    assert np.all(np.diff([f.timestamp_ms for f in frames]) == 50)  # interval 1: every other scan
    assert not fake.model.laser_on


class _RecordingSource:
    """FixedRoom that records, per call, the first beam's index and count and the model's clock then."""

    def __init__(self, clock: list[float]) -> None:
        self.room, self.clock, self.calls = FixedRoom(), clock, []

    def sweep(self, t0_s: float, angles_rad: np.ndarray, beam_dt_s: float) -> tuple[np.ndarray, np.ndarray]:
        first = int(round(float(angles_rad[0]) / (2 * np.pi / 1440))) + 540
        self.calls.append((t0_s, first, angles_rad.size, self.clock[0]))
        return self.room.sweep(t0_s, angles_rad, beam_dt_s)  # type: ignore[no-any-return]


def test_sweep_is_measured_as_its_beams_are_taken_and_only_for_scans_sent() -> None:
    clock = [0.0]
    source = _RecordingSource(clock)
    model = Utm30lxModel(Utm30lxConfig(link_bytes_per_s=0.0), source=source)
    out = bytearray()
    model.attach(out.extend)
    model.poll(0.0)
    clock[0] = t = 0.001
    model.on_bytes(b"MD0000108001102\n", t)  # mid-sweep; interval 1: every other scan; two scans
    while t < 0.15:
        t += 0.0005
        clock[0] = t
        model.poll(t)
    step_dt = 0.025 / 1440
    by_scan: dict[int, list[tuple[float, int, int, float]]] = {}
    for call in source.calls:
        by_scan.setdefault(int(round(call[0] / 0.025 - 0.4)), []).append(call)
    assert sorted(by_scan) == [1, 3]  # scans 0 (mid-request), 2 (skipped by the interval), 4+ never measured
    for k, calls in by_scan.items():
        firsts = [c[1] for c in calls]
        assert firsts[0] == 0 and sum(c[2] for c in calls) == 1081  # every beam once, in order
        assert all(a[1] + a[2] == b[1] for a, b in zip(calls, calls[1:]))
        for t0, first, count, measured_at in calls:
            assert t0 == pytest.approx(k * 0.025 + first * step_dt)
            last_beam_s = t0 + (count - 1) * step_dt
            assert last_beam_s <= measured_at <= last_beam_s + 3 * step_dt + 0.0005  # taken, then measured
        assert len(calls) > 1
    frames = [e for e in ScipDecoder().feed(bytes(out)) if isinstance(e, ScanFrame)]
    assert len(frames) == 2 and all(f.distances.size == 1081 for f in frames)
    whole = np.round(FixedRoom().sweep(0, (np.arange(1081) - 540) * 2 * np.pi / 1440, 0)[0] * 1000)
    assert frames[0].distances.tolist() == whole.astype(int).tolist()


def test_link_pace_delays_each_message_by_its_size() -> None:
    rate = 840_000.0
    fake = Driven(Utm30lxConfig(link_bytes_per_s=rate), paced=True)
    assert fake.send(b"VV") == b""  # not across the link yet
    vv = fake.advance(0.001, step=0.00005)
    assert vv.startswith(b"VV\n00P\n")
    t_md = fake.t
    fake.send(b"MD0000108001001")
    arrivals: list[tuple[float, int]] = []
    while fake.t < t_md + 0.08:
        chunk = fake.advance(0.0001, step=0.0001)
        if chunk:
            arrivals.append((fake.t, len(chunk)))
    ack_t, ack_len = arrivals[0]
    frame_t, frame_len = arrivals[1]
    assert ack_len == len(b"MD0000108001001\n00P\n\n")
    assert ack_t == pytest.approx(t_md + ack_len / rate, abs=2e-4)
    assert frame_len > 3300  # 1081 steps, 3 characters each, 64 per line with sum and LF
    boot = 100.0
    done = boot + (int(np.ceil((t_md - boot) / 0.025)) * 0.025) + 1081 * 0.025 / 1440
    assert frame_t == pytest.approx(done + frame_len / rate, abs=2e-4)  # from the sweep's end, ~4 ms


def test_cluster_and_short_encoding() -> None:
    fake = Driven()
    fake.send(b"BM")
    [gd] = ScipDecoder().feed(fake.send(b"GD0000108003") + fake.advance(0.05))
    assert isinstance(gd, ScanFrame) and gd.distances.size == 361
    [gs] = ScipDecoder().feed(fake.send(b"GS0540054000") + fake.advance(0.05))
    assert isinstance(gs, ScanFrame) and gs.distances.size == 1 and gs.distances[0] <= 4095


def test_range_source_units_and_error_codes() -> None:
    class Source:
        def sweep(self, t0_s: float, angles_rad: np.ndarray, beam_dt_s: float) -> tuple[np.ndarray, np.ndarray]:
            r = np.full(angles_rad.shape, 1.5)
            r[0] = np.nan  # no return -> 1
            r[1] = 0.01  # below DMIN -> 2
            r[2] = 70.0  # beyond DMAX -> 1
            return r, np.full(angles_rad.shape, 321.4)

    model = Utm30lxModel(source=Source())
    out = bytearray()
    model.attach(out.extend)
    model.poll(0.0)
    model.on_bytes(b"BM\nGE0000108001\n", 0.0)
    model.poll(0.05)
    frames = [e for e in ScipDecoder().feed(bytes(out)) if isinstance(e, ScanFrame)]
    assert len(frames) == 1 and frames[0].intensities is not None
    assert frames[0].distances[:4].tolist() == [1, 2, 1, 1500]
    assert set(frames[0].intensities.tolist()) == {321}


# ------------------------------------------------------------------ statuses


@pytest.mark.parametrize(
    "request_line, code",
    [
        (b"TM1", "04"), (b"TM2", "03"), (b"TM7", "01"), (b"TM", "0C"),
        (b"GD0000108001", "10"),  # laser off after QT below
        (b"MDx000108001000", "01"), (b"MD0000x08001000", "02"), (b"MD00001080x1000", "03"),
        (b"MD0000108001x00", "06"), (b"MD000010800100x", "07"), (b"MD0000200001000", "04"),
        (b"MD0500010001000", "05"), (b"MD00001080", "0C"),
        (b"QT;" + b"a" * 17, "0G"), (b"QT;bad!", "0H"),
        (b"XX", "0E"), (b"ND0000108001000", "0E"), (b"%ST", "0E"), (b"CR00", "04"), (b"SS115200", "00"),
        (b"SS123456", "02"), (b"HS1", "03"), (b"VV1", "0C"),
    ],
)
def test_error_statuses(request_line: bytes, code: str) -> None:
    fake = Driven(Utm30lxConfig(laser_on_at_start=False))
    reply = fake.send(request_line) + fake.advance(0.05)
    expected = request_line + b"\n" + code.encode() + scip_sum(code.encode()) + b"\n\n"
    assert reply == expected


def test_time_adjust_mode() -> None:
    fake = Driven()
    assert fake.send(b"TM0") == b"TM0\n00P\n\n"
    assert not fake.model.laser_on  # TM mode switches the laser off
    assert fake.send(b"TM0") == b"TM0\n02R\n\n"
    assert fake.send(b"BM") == b"BM\n0Ee\n\n"  # refused until TM2
    values = []
    for _ in range(6):
        [ev] = ScipDecoder().feed(fake.send(b"TM1", dt=0.001))
        assert isinstance(ev, TimeReply)
        values.append(ev.timestamp_ms)
    assert values == sorted(values) and values[-1] - values[0] == 5
    assert fake.send(b"TM2") == b"TM2\n00P\n\n"
    assert fake.send(b"BM") == b"BM\n00P\n\n"
    assert fake.send(b"BM") == b"BM\n02R\n\n"


def test_rs_resets_the_clock_and_rb_needs_two() -> None:
    fake = Driven()
    fake.advance(1.0)
    assert fake.send(b"RS") == b"RS\n00P\n\n"
    assert fake.send(b"TM0", dt=0.01) == b"TM0\n00P\n\n"
    [ev] = ScipDecoder().feed(fake.send(b"TM1", dt=0.005))
    assert isinstance(ev, TimeReply) and ev.timestamp_ms < 100
    fake.send(b"TM2")
    assert fake.send(b"RB") == b"RB\n01Q\n\n"
    assert fake.send(b"RB", dt=0.2) == b"RB\n00P\n\n"


def test_crlf_and_cr_terminated_requests() -> None:
    fake = Driven()
    start = len(fake.out)
    fake.model.on_bytes(b"QT\r\nBM\rVV", fake.t)
    fake.model.on_bytes(b"\r\n", fake.t)
    events = ScipDecoder().feed(bytes(fake.out[start:]))
    assert [e.echo for e in events] == ["QT", "BM", "VV"]  # type: ignore[union-attr]


def test_fake_does_not_import_the_driver() -> None:
    package = Path(__file__).resolve().parents[2] / "hil_fakes" / "utm30lx"
    for source in package.glob("*.py"):
        assert "drivers" not in {line.split()[1].split(".")[0] for line in source.read_text().splitlines()
                                 if line.startswith(("import ", "from "))}


def test_wire_helpers() -> None:
    assert encode(np.array([4821609]), 4) == b"BI9Y"
    block = data_block(b"0" * 130)
    assert [len(x) for x in block.split(b"\n")[:-1]] == [65, 65, 3]


# ------------------------------------------------------------------ urg_library's wire sequences


class RawLink:
    """Raw bytes to the fake, as a C program would send them (no driver code in the path)."""

    def __init__(self, server: DeviceServer) -> None:
        self.sock: socket.socket | None = None
        self.fd = -1
        address = server.address
        if address.startswith("socket://"):
            host, port = address[len("socket://") :].rsplit(":", 1)
            self.sock = socket.create_connection((host, int(port)), timeout=5.0)
        else:
            self.fd = os.open(address, os.O_RDWR | os.O_NOCTTY)
            tty.setraw(self.fd)
        self.decoder = ScipDecoder()
        self.pending: list[object] = []

    def write(self, data: bytes) -> None:
        if self.sock is not None:
            self.sock.sendall(data)
        else:
            os.write(self.fd, data)

    def _read(self, timeout_s: float) -> bytes:
        src = self.sock if self.sock is not None else self.fd
        ready, _, _ = select.select([src], [], [], timeout_s)
        if not ready:
            return b""
        return self.sock.recv(65536) if self.sock is not None else os.read(self.fd, 65536)

    def events(self, count: int, timeout_s: float = 10.0) -> list[object]:
        deadline = time.monotonic() + timeout_s
        while len(self.pending) < count and time.monotonic() < deadline:
            self.pending.extend(self.decoder.feed(self._read(0.05)))
        got, self.pending = self.pending[:count], self.pending[count:]
        assert len(got) == count, f"only {len(got)} of {count} replies"
        return got

    def until_echo(self, echo: str, timeout_s: float = 10.0) -> tuple[list[object], object]:
        skipped: list[object] = []
        while True:
            ev = self.events(1, timeout_s)[0]
            if getattr(ev, "echo", None) == echo:
                return skipped, ev
            skipped.append(ev)

    def silent_for(self, seconds: float) -> bool:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            if self._read(0.02):
                return False
        return True

    def close(self) -> None:
        if self.sock is not None:
            self.sock.close()
        if self.fd >= 0:
            os.close(self.fd)


@pytest.fixture(params=["pty", "tcp"])
def link(request: pytest.FixtureRequest) -> Iterator[RawLink]:
    endpoint = PtyEndpoint() if request.param == "pty" else TcpEndpoint()
    server = DeviceServer(Utm30lxModel(), endpoint).start()
    time.sleep(0.05)
    raw = RawLink(server)
    yield raw
    raw.close()
    server.stop()


def test_get_distance_sequence(link: RawLink) -> None:
    link.write(b"\n")
    assert link.silent_for(0.14)  # urg_library drains 140 ms after the bare LF: nothing comes
    link.write(b"QT\n")
    [qt] = link.events(1)
    assert isinstance(qt, StatusReply) and qt.status.code == "00"
    link.write(b"PP\n")
    link.events(1)
    link.write(b"MD0000108001000\n")
    ack, *frames = link.events(11)
    assert isinstance(ack, StatusReply) and ack.status.code == "00"
    assert all(isinstance(f, ScanFrame) and f.distances.size == 1081 for f in frames)
    link.write(b"QT\n")
    skipped, qt2 = link.until_echo("QT")
    assert all(isinstance(f, ScanFrame) for f in skipped)
    assert isinstance(qt2, StatusReply) and qt2.status.code == "00"
    assert link.silent_for(0.1)


def test_calculate_xy_sequence(link: RawLink) -> None:
    link.write(b"BM\n")
    [bm] = link.events(1)
    assert isinstance(bm, StatusReply) and bm.status.success  # 02: already on at start
    link.write(b"GD0000108000\n")
    [gd] = link.events(1)
    assert isinstance(gd, ScanFrame) and gd.distances.size == 1081 and gd.status.code == "00"


def test_get_distance_intensity_sequence(link: RawLink) -> None:
    link.write(b"ME0000108000001\n")
    ack, frame = link.events(2)
    assert isinstance(ack, StatusReply) and ack.status.code == "00"
    assert isinstance(frame, ScanFrame) and frame.intensities is not None and frame.remaining == 0
    assert link.silent_for(0.1)


def test_sync_time_stamp_sequence(link: RawLink) -> None:
    link.write(b"TM0\n")
    assert link.events(1)[0].status.code == "00"  # type: ignore[attr-defined]
    values = []
    for _ in range(6):
        link.write(b"TM1\n")
        [ev] = link.events(1)
        assert isinstance(ev, TimeReply)
        values.append(ev.timestamp_ms)
    assert values == sorted(values)
    link.write(b"TM2\n")
    assert link.events(1)[0].status.code == "00"  # type: ignore[attr-defined]


def test_sensor_parameter_and_multiecho_sequences(link: RawLink) -> None:
    link.write(b"VV\nII\n")
    vv, ii = link.events(2)
    assert isinstance(vv, VersionReply) and isinstance(ii, StateReply)
    assert vv.info.serial == "00903971" and ii.info.model.startswith("UTM-30LX")
    link.write(b"ND0000108001000\n")
    [nd] = link.events(1)
    assert isinstance(nd, StatusReply) and nd.status.code == "0E"
