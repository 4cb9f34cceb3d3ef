"""Fuzz tests of the ARCOS deframer (issue 12, row 10): a tiny frame (count 3 or 4, whose checksum
equals its payload) cannot swallow the header of the frame after it; any junk followed by a valid
frame yields that frame, however the stream is split; the held buffer stays bounded."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from drivers.p2os import codec as c

_SIP = c.frame(bytes([0x32]) + bytes(range(1, 30)))


def _split_feed(stream: bytes, cuts: list[int]) -> list[c.RawFrame | c.BadFrame]:
    """Feed in pieces, then expire partial frames as the client does when no progress is seen."""
    deframer = c.Deframer()
    out: list[c.RawFrame | c.BadFrame] = []
    last = 0
    for cut in sorted(x for x in cuts if x <= len(stream)) + [len(stream)]:
        out += deframer.feed(stream[last:cut])
        last = cut
    while expired := deframer.expire_partial():
        out += expired
    return out


@pytest.mark.parametrize("junk", ["fafb03fa00", "fafb0401fa01", "00fafb03fa00"])
def test_tiny_frame_does_not_swallow_the_next_header(junk: str) -> None:
    deframer = c.Deframer()
    out = deframer.feed(bytes.fromhex(junk) + _SIP)
    assert [e for e in out if isinstance(e, c.RawFrame)] == [c.RawFrame(_SIP[3:-2])]
    assert any(isinstance(e, c.BadFrame) and e.kind is c.BadFrameKind.OVERLAP for e in out)
    assert deframer.stats.overlap_rejects == 1 and deframer.pending == 0


def test_a_tiny_frame_ending_in_fa_is_held_then_released_on_expiry() -> None:
    deframer = c.Deframer()
    assert deframer.feed(c.frame(b"\xfa")) == []
    assert deframer.expire_partial() == [c.RawFrame(b"\xfa")]
    assert deframer.pending == 0 and deframer.stats.truncated == 0


def test_a_real_sync_echo_before_a_sip_still_decodes() -> None:
    out = c.Deframer().feed(c.frame(b"\x01") + _SIP)
    assert out == [c.RawFrame(b"\x01"), c.RawFrame(_SIP[3:-2])]


@settings(max_examples=300, deadline=None)
@given(junk=st.binary(max_size=40), cuts=st.lists(st.integers(min_value=0, max_value=80), max_size=4))
def test_junk_then_a_valid_frame_yields_it_however_split(junk: bytes, cuts: list[int]) -> None:
    stream = junk + _SIP
    whole = _split_feed(stream, [])
    assert _split_feed(stream, cuts) == whole
    assert [e for e in whole if isinstance(e, c.RawFrame)][-1] == c.RawFrame(_SIP[3:-2])


@settings(max_examples=200, deadline=None)
@given(data=st.binary(max_size=600))
def test_arbitrary_bytes_never_raise_and_hold_at_most_one_frame(data: bytes) -> None:
    deframer = c.Deframer()
    out = deframer.feed(data)
    assert all(isinstance(e, c.RawFrame | c.BadFrame) for e in out)
    assert deframer.pending <= c.MAX_COUNT + 3
