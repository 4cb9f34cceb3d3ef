"""Golden tests: the codec decodes the real recorded UTM-30LX and UXM-30LX-E sessions exactly.

The reference values come from shared/data/hokuyo_utm30lx_session/PROVENANCE.md; the full ME frame
is also checked against a deliberately naive per-character decoder written here.
"""

from __future__ import annotations

import random
from pathlib import Path

import numpy as np
import pytest

from drivers.hokuyo_scip.codec import (
    ParametersReply,
    ScanFrame,
    ScipDecoder,
    StateReply,
    StatusMeaning,
    StatusReply,
    TimeReply,
    VersionReply,
)

from .helpers import load_session, sensor_bytes


def _decode_recorded(records: list[tuple[float, str, bytes]]) -> list[object]:
    """Feed the sensor side exactly as the host read it (one record per read)."""
    decoder = ScipDecoder()
    events: list[object] = []
    for _, direction, payload in records:
        if direction == "sensor_to_host":
            events.extend(decoder.feed(payload))
    assert decoder.buffered == 0
    assert decoder.errors == 0
    return events


def _naive_frame_values(raw: bytes, echo: bytes) -> tuple[int, list[int]]:
    """Independent reference: split lines, check nothing, decode char by char (3 chars per value)."""
    start = raw.index(echo + b"\n99b\n")
    end = raw.index(b"\n\n", start)
    lines = raw[start:end].split(b"\n")
    ts_chars = lines[2][:4]
    ts = 0
    for ch in ts_chars:
        ts = ts * 64 + (ch - 0x30)
    data = b"".join(line[:-1] for line in lines[3:])
    values = []
    for i in range(0, len(data), 3):
        v = 0
        for ch in data[i : i + 3]:
            v = v * 64 + (ch - 0x30)
        values.append(v)
    return ts, values


@pytest.fixture(scope="module")
def utm_records(shared_data: Path) -> list[tuple[float, str, bytes]]:
    return load_session(shared_data, "example_utm_30lx")


@pytest.fixture(scope="module")
def uxm_records(shared_data: Path) -> list[tuple[float, str, bytes]]:
    return load_session(shared_data, "example_uxm_30lx_e")


def test_utm30lx_session_event_sequence(utm_records: list[tuple[float, str, bytes]]) -> None:
    events = _decode_recorded(utm_records)
    kinds = [(type(e).__name__, getattr(e, "echo", None)) for e in events]
    assert kinds == [
        ("VersionReply", "VV"),
        ("VersionReply", "VV"),
        ("ParametersReply", "PP"),
        ("StateReply", "II"),
        ("StatusReply", "BM"),
        ("StatusReply", "CR00"),
        ("VersionReply", "VV"),
        ("ParametersReply", "PP"),
        ("StateReply", "II"),
        ("StatusReply", "ME0000108001101"),
        ("ScanFrame", "ME0000108001100"),
    ]


def test_utm30lx_info_values(utm_records: list[tuple[float, str, bytes]]) -> None:
    events = _decode_recorded(utm_records)
    vv = events[0]
    assert isinstance(vv, VersionReply)
    assert dict(vv.values) == {
        "VEND": "Hokuyo Automatic Co.,Ltd.",
        "PROD": "SOKUIKI Sensor TOP-URG UTM-30LX",
        "FIRM": "P.1.05(17/Apr./2009)",
        "PROT": "SCIP 2.0",
        "SERI": "00903971",
    }
    assert vv.info.serial == "00903971" and vv.info.firmware == "P.1.05(17/Apr./2009)"
    pp = events[2]
    assert isinstance(pp, ParametersReply)
    p = pp.info
    assert (p.model, p.dmin_mm, p.dmax_mm, p.ares, p.amin, p.amax, p.afrt, p.scan_rpm) == (
        "UTM-30LX(Hokuyo Automatic Co.,Ltd.)", 23, 60000, 1440, 0, 1080, 540, 2400,
    )
    assert p.n_steps == 1081
    assert p.scan_period_s == pytest.approx(0.025)
    assert p.step_bearing_rad(0) == pytest.approx(-3 * np.pi / 4)
    assert p.step_bearing_rad(540) == pytest.approx(0.0)
    ii1, ii2 = events[3], events[8]
    assert isinstance(ii1, StateReply) and isinstance(ii2, StateReply)
    assert ii1.values["TIME"] == "4991D0" and ii1.info.time_ms == 4821456
    assert ii2.values["TIME"] == "49924D" and ii2.info.time_ms == 4821581
    s = ii1.info
    assert s.laser_on is True
    assert s.motor_speed == "Initial(2400[rpm])<-Default setting by user"
    assert (s.measurement_mode, s.bit_rate, s.status_text) == ("CLASSIC", "USB Full Speed", "Sensor works well.")
    # firmware P.1.05 sums the whole SCSP text: no '<-' fallback needed
    assert ii1.checksum_fallback_keys == ()


def test_utm30lx_status_replies(utm_records: list[tuple[float, str, bytes]]) -> None:
    events = _decode_recorded(utm_records)
    bm, cr, ack = events[4], events[5], events[9]
    assert isinstance(bm, StatusReply) and isinstance(cr, StatusReply) and isinstance(ack, StatusReply)
    assert bm.status.code == "02" and bm.status.success and bm.status.meaning is StatusMeaning.ALREADY_SET
    assert cr.status.code == "04" and not cr.status.success and cr.status.meaning is StatusMeaning.NOT_SUPPORTED
    assert ack.status.code == "00" and ack.status.success and ack.payload == ()


def test_utm30lx_me_frame_exact(utm_records: list[tuple[float, str, bytes]]) -> None:
    events = _decode_recorded(utm_records)
    frame = events[10]
    assert isinstance(frame, ScanFrame)
    assert frame.status.code == "99" and frame.status.meaning is StatusMeaning.SCAN_DATA
    assert frame.remaining == 0
    assert frame.timestamp_ms == 4821609
    assert frame.request.start == 0 and frame.request.end == 1080 and frame.request.cluster == 1
    d, i = frame.distances, frame.intensities
    assert i is not None
    assert d.shape == (1081,) and i.shape == (1081,)
    assert (int(d[0]), int(d[540]), int(d[1080])) == (45, 3298, 49)
    assert int(d.min()) == 45 and int(d.max()) == 5856
    assert int(i.min()) == 137 and int(i.max()) == 16219
    assert float(np.median(i)) == 2439.0
    assert not (d < 23).any()
    # every one of the 1081 pairs against the naive reference decoder
    ts, values = _naive_frame_values(sensor_bytes(utm_records), b"ME0000108001100")
    assert ts == 4821609
    assert len(values) == 2162
    assert d.tolist() == values[0::2]
    assert i.tolist() == values[1::2]


def test_utm30lx_session_any_chunking(utm_records: list[tuple[float, str, bytes]]) -> None:
    raw = sensor_bytes(utm_records)
    whole = _decode_recorded([(0.0, "sensor_to_host", raw)])
    rng = random.Random(7)
    for _ in range(5):
        decoder = ScipDecoder()
        events: list[object] = []
        pos = 0
        while pos < len(raw):
            n = rng.randint(1, 900)
            events.extend(decoder.feed(raw[pos : pos + n]))
            pos += n
        assert [type(e) for e in events] == [type(e) for e in whole]
        assert isinstance(events[-1], ScanFrame) and isinstance(whole[-1], ScanFrame)
        assert np.array_equal(events[-1].distances, whole[-1].distances)


def test_utm30lx_session_with_crlf_line_ends(utm_records: list[tuple[float, str, bytes]]) -> None:
    raw = sensor_bytes(utm_records).replace(b"\n", b"\r\n")
    events = ScipDecoder().feed(raw)
    assert len(events) == 11 and isinstance(events[-1], ScanFrame)
    assert events[-1].timestamp_ms == 4821609


def test_uxm30lx_tm1_values_and_gd_frame(uxm_records: list[tuple[float, str, bytes]]) -> None:
    events = _decode_recorded(uxm_records)
    tm1 = [e.timestamp_ms for e in events if isinstance(e, TimeReply)]
    assert tm1 == [3292603, 3292604, 3292605, 3292606, 3292607, 3292607, 3292608, 3292609, 3292610, 3292611]
    tm_status = [e for e in events if isinstance(e, StatusReply) and e.echo in ("TM0", "TM2")]
    assert [e.status.code for e in tm_status] == ["00", "00"]
    gd = [e for e in events if isinstance(e, ScanFrame)]
    assert len(gd) == 1
    frame = gd[0]
    assert frame.echo == "GD0000076001" and frame.remaining is None
    assert frame.timestamp_ms == 3293169
    assert frame.distances.shape == (761,)
    assert int(frame.distances[380]) == 2243
    assert int(frame.distances.min()) == 337 and int(frame.distances.max()) == 3179
    pp = next(e for e in events if isinstance(e, ParametersReply))
    assert (pp.info.dmin_mm, pp.info.amax, pp.info.afrt, pp.info.scan_rpm) == (100, 760, 380, 1200)
    states = [e for e in events if isinstance(e, StateReply)]
    assert [s.info.measurement_mode for s in states] == ["STANDARD(max:100000[mm])", "CLASSIC"]
    bm = next(e for e in events if isinstance(e, StatusReply) and e.echo == "BM")
    assert bm.status.code == "00"
