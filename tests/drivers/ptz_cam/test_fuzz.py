"""Fuzz tests of the VISCA reply framer (issue 12, row 6): a corrupt or unterminated fragment
followed by a valid reply yields that reply, whatever the fragment and however the stream is split."""

from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st

from drivers.ptz_cam import visca as v

_VALID_REPLIES = [
    bytes.fromhex("9041ff"),  # ack, socket 1
    bytes.fromhex("9051ff"),  # completion, socket 1
    bytes.fromhex("906102ff"),  # syntax error, socket 1
    bytes.fromhex("905000000000ff"),  # an inquiry answer
    bytes.fromhex("883002ff"),  # AddressSet
]


def _replies(events: list[v.Event]) -> list[v.Event]:
    return [e for e in events if not isinstance(e, v.Discarded)]


def test_unterminated_fragment_does_not_swallow_the_next_reply() -> None:
    # the audit's case: `90 50` then `90 51 FF` decoded as an inquiry answer with data `90 51`
    events = v.ViscaParser().feed(bytes.fromhex("9050") + bytes.fromhex("9051ff"))
    assert _replies(events) == [v.Completion(address=1, socket=1, raw=bytes.fromhex("9051ff"))]
    assert isinstance(events[0], v.Discarded) and events[0].raw == bytes.fromhex("9050")


def test_unterminated_fragment_does_not_swallow_an_error_reply() -> None:
    events = v.ViscaParser().feed(bytes.fromhex("905000") + bytes.fromhex("906102ff"))
    assert [type(e) for e in _replies(events)] == [v.ErrorReply]
    assert _replies(events)[0].raw == bytes.fromhex("906102ff")


@settings(max_examples=300, deadline=None)
@given(
    junk=st.binary(max_size=40),
    reply=st.sampled_from(_VALID_REPLIES),
    cuts=st.lists(st.integers(min_value=0, max_value=60), max_size=4),
)
def test_corrupt_then_valid_yields_the_valid_reply_however_split(junk: bytes, reply: bytes, cuts: list[int]) -> None:
    # junk ends with a terminator, as a corrupt packet on the wire would; then the valid reply
    stream = junk + b"\xff" + reply
    whole = v.ViscaParser().feed(stream)
    parser = v.ViscaParser()
    split: list[v.Event] = []
    last = 0
    for cut in sorted(c for c in cuts if c <= len(stream)) + [len(stream)]:
        split += parser.feed(stream[last:cut])
        last = cut
    assert split == whole
    assert _replies(whole)[-1].raw == reply
    assert parser.pending == 0


@settings(max_examples=300, deadline=None)
@given(data=st.binary(max_size=200))
def test_arbitrary_bytes_keep_the_buffer_bounded(data: bytes) -> None:
    # every byte is accounted for: in a reply, in a Discarded event, or still pending
    parser = v.ViscaParser()
    events: list[v.Event] = []
    for byte in data:
        events += parser.feed(bytes([byte]))
        assert parser.pending <= v.MAX_PACKET - 1
    assert sum(len(e.raw) for e in events) + parser.pending == len(data)
    assert parser.discarded_bytes == sum(len(e.raw) for e in events if isinstance(e, v.Discarded))
