"""The live view front's sans-I/O WebSocket pieces: frames read whole however the bytes are split,
masks removed, sizes bounded; upgrade heads checked; subprotocol names chosen and renamed."""

from __future__ import annotations

import struct

import pytest
from hypothesis import given
from hypothesis import strategies as st

from app import wsframes as wf


def _frame(opcode: int, payload: bytes, mask: bytes = b"", fin: bool = True) -> bytes:
    n = len(payload)
    b0 = (0x80 if fin else 0) | opcode
    mbit = 0x80 if mask else 0
    if n < 126:
        head = struct.pack(">BB", b0, mbit | n)
    elif n < 1 << 16:
        head = struct.pack(">BBH", b0, mbit | 126, n)
    else:
        head = struct.pack(">BBQ", b0, mbit | 127, n)
    body = bytes(b ^ mask[i % 4] for i, b in enumerate(payload)) if mask else payload
    return head + mask + body


@given(st.lists(st.binary(max_size=70_000), min_size=1, max_size=4), st.integers(1, 5000), st.booleans())
def test_frames_are_read_whole_and_unmasked_however_the_stream_is_split(payloads: list[bytes], step: int,
                                                                       masked: bool) -> None:
    stream = b"".join(_frame(wf.OP_BINARY, p, b"\x01\x02\x03\x04" if masked else b"") for p in payloads)
    reader = wf.FrameReader(1 << 20)
    got = []
    for i in range(0, len(stream), step):
        got += reader.feed(stream[i:i + step])
    assert [f.payload for f in got] == payloads and b"".join(f.raw for f in got) == stream
    assert reader.buffered == 0


def test_an_oversized_frame_and_reserved_bits_are_frame_errors() -> None:
    with pytest.raises(wf.FrameError, match="at most 10"):
        wf.FrameReader(10).feed(_frame(wf.OP_TEXT, b"x" * 11))
    with pytest.raises(wf.FrameError, match="reserved"):
        wf.FrameReader(10).feed(bytes([0xC1, 0x01]) + b"x")  # RSV1: compressed, never agreed


def test_message_data_frames_are_recognised_and_built() -> None:
    raw = wf.message_data_frame(7, 123, b"{}")
    (frame,) = wf.FrameReader(100).feed(raw)
    assert frame.is_message_data() and frame.payload == struct.pack("<BIQ", 1, 7, 123) + b"{}"
    assert not wf.FrameReader(100).feed(_frame(wf.OP_BINARY, b"\x02time", fin=True))[0].is_message_data()
    assert not wf.FrameReader(100).feed(_frame(wf.OP_BINARY, b"\x01", fin=False))[0].is_message_data()
    close = wf.client_close_frame(b"\x09\x08\x07\x06")
    (frame,) = wf.FrameReader(100).feed(close)
    assert frame.opcode == wf.OP_CLOSE and frame.payload == struct.pack(">H", 1000)


def test_request_heads_are_checked() -> None:
    head = (b"GET / HTTP/1.1\r\nHost: x\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
            b"Sec-WebSocket-Protocol: a, foxglove.websocket.v1\r\nSec-WebSocket-Extensions: permessage-deflate\r\n\r\n")
    assert wf.head_end(head[:-1]) == -1 and wf.head_end(head) == len(head)
    req = wf.parse_request_head(head)
    assert req.values("sec-websocket-protocol") == ["a", "foxglove.websocket.v1"]
    out = wf.backend_request(req, wf.SDK_SUBPROTOCOL)
    assert b"Sec-WebSocket-Protocol: foxglove.sdk.v1\r\n" in out and b"Extensions" not in out
    bad_heads = [(b"POST / HTTP/1.1\r\n\r\n", 400), (b"GET / HTTP/1.1\r\nHost: x\r\n\r\n", 426),
                 (b"GET / HTTP/1.1\r\nbad line\r\n\r\n", 400), ("GET / HTTP/1.1\r\nX: \u00e9\r\n\r\n".encode(), 400)]
    for bad, status in bad_heads:
        with pytest.raises(wf.HandshakeError) as info:
            wf.parse_request_head(bad)
        assert info.value.status == status
    with pytest.raises(wf.HandshakeError) as info:
        wf.head_end(b"x" * (wf.MAX_HEAD_BYTES + 1))
    assert info.value.status == 431


@pytest.mark.parametrize(("offered", "ask", "answer"), [
    (["foxglove.sdk.v1"], "foxglove.sdk.v1", ""),
    (["foxglove.websocket.v1", "foxglove.sdk.v1"], "foxglove.websocket.v1, foxglove.sdk.v1", ""),
    (["foxglove.websocket.v1"], "foxglove.sdk.v1", "foxglove.websocket.v1"),
])
def test_the_older_subprotocol_name_is_asked_of_the_sdk_by_its_new_name(offered: list[str], ask: str,
                                                                        answer: str) -> None:
    assert wf.choose_subprotocol(offered) == (ask, answer)
    resp = b"HTTP/1.1 101 Switching Protocols\r\nsec-websocket-protocol: foxglove.sdk.v1\r\n\r\n"
    assert wf.response_status(resp) == 101
    renamed = wf.rename_response_subprotocol(resp, answer)
    assert renamed == resp if not answer else b"Sec-WebSocket-Protocol: foxglove.websocket.v1" in renamed


def test_a_client_offering_no_foxglove_subprotocol_is_told_which_are_served() -> None:
    with pytest.raises(wf.HandshakeError, match="foxglove.sdk.v1 or foxglove.websocket.v1") as info:
        wf.choose_subprotocol([])
    assert info.value.status == 400 and wf.http_error(400, "x").startswith(b"HTTP/1.1 400 Bad Request\r\n")
