"""The IDL types of ``app.ros2.msgs`` against the ROS 2 ``.msg`` definitions (``rosbags``' type
stores for Humble and Jazzy, and the ``radar_msgs`` text kept beside the types): every field's name,
order and type, every constant; and bytes written by ``cyclonedds`` decoded by ``rosbags``' CDR reader
to the same values (wire compatibility with ROS 2, no ROS needed)."""

from __future__ import annotations

import dataclasses
import itertools
import typing

import numpy as np
import pytest
from cyclonedds.idl import IdlStruct
from cyclonedds.idl.types import array, sequence
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.base import Nodetype

from app.ros2 import msgs

ROS_NAME = {cls: name for name, cls in msgs.ROS_TYPES.items()}
CONSTANTS = {
    "visualization_msgs/msg/Marker": msgs.MarkerConst,
    "diagnostic_msgs/msg/DiagnosticStatus": msgs.DiagnosticLevel,
    "radar_msgs/msg/RadarTrack": msgs.RadarClassification,
}


def typestore(store: Stores) -> typing.Any:
    ts = get_typestore(store)
    for name, text in msgs.RADAR_MSGS.items():
        ts.register(get_types_from_msg(text, name))
    return ts


STORES = {"humble": typestore(Stores.ROS2_HUMBLE), "jazzy": typestore(Stores.ROS2_JAZZY)}


def idl_fielddef(hint: typing.Any) -> tuple[typing.Any, ...]:
    """A binding's field type written as ``rosbags`` writes a ``.msg`` field."""
    if isinstance(hint, type) and issubclass(hint, IdlStruct):
        return (Nodetype.NAME, ROS_NAME[hint])
    if hint is str:
        return (Nodetype.BASE, ("string", 0))
    if hint is bool:
        return (Nodetype.BASE, ("bool", 0))
    meta = typing.get_args(hint)[1]
    if isinstance(meta, sequence):
        return (Nodetype.SEQUENCE, (idl_fielddef(meta.subtype), meta.max_length or 0))
    if isinstance(meta, array):
        return (Nodetype.ARRAY, (idl_fielddef(meta.subtype), meta.length))
    return (Nodetype.BASE, (meta, 0))


def idl_fields(cls: type) -> list[tuple[str, typing.Any]]:
    hints = typing.get_type_hints(cls, include_extras=True)
    return [(f.name, idl_fielddef(hints[f.name])) for f in dataclasses.fields(cls)]


@pytest.mark.parametrize("store", sorted(STORES))
@pytest.mark.parametrize("ros_type", sorted(msgs.ROS_TYPES))
def test_fields_match_the_msg_definition(ros_type: str, store: str) -> None:
    consts, fields = STORES[store].fielddefs[ros_type]
    assert idl_fields(msgs.ROS_TYPES[ros_type]) == list(fields)
    pkg, _, name = ros_type.split("/")
    assert msgs.ROS_TYPES[ros_type].__idl_typename__ == f"{pkg}::msg::dds_::{name}_"
    enum = CONSTANTS.get(ros_type)
    ours = {} if enum is None else {m: int(v) for m, v in enum.__members__.items()}
    theirs = {cname: value for cname, _, value in consts}
    if store == "jazzy" and ros_type == "visualization_msgs/msg/Marker":
        assert theirs.pop("ARROW_STRIP") == 12  # new in Jazzy, unused here
    assert ours == theirs


def filled(cls: type, counter: itertools.count[int]) -> typing.Any:
    """An instance with a distinct non-default value in every field (sequences of two)."""
    hints = typing.get_type_hints(cls, include_extras=True)
    return cls(**{f.name: value_for(hints[f.name], counter) for f in dataclasses.fields(cls)})


def value_for(hint: typing.Any, counter: itertools.count[int]) -> typing.Any:
    if isinstance(hint, type) and issubclass(hint, IdlStruct):
        return filled(hint, counter)
    if hint is str:
        return f"s{next(counter)}"
    if hint is bool:
        return next(counter) % 2 == 1
    meta = typing.get_args(hint)[1]
    if isinstance(meta, sequence | array):
        n = meta.length if isinstance(meta, array) else 2
        return [value_for(meta.subtype, counter) for _ in range(n)]
    k = next(counter) % 100 + 1
    return k + 0.5 if meta.startswith("float") else k


def assert_same(ours: typing.Any, theirs: typing.Any, where: str) -> None:
    if isinstance(ours, IdlStruct):
        for f in dataclasses.fields(ours):
            assert_same(getattr(ours, f.name), getattr(theirs, f.name), f"{where}.{f.name}")
    elif isinstance(ours, list | bytes):
        assert len(ours) == len(theirs), where
        for i, (a, b) in enumerate(zip(ours, theirs, strict=True)):
            assert_same(a, b, f"{where}[{i}]")
    else:
        assert ours == (theirs.item() if isinstance(theirs, np.generic) else theirs), where
        assert type(ours) is type(theirs.item() if isinstance(theirs, np.generic) else theirs), where


@pytest.mark.parametrize("ros_type", sorted(msgs.ROS_TYPES))
def test_cdr_bytes_decode_in_rosbags(ros_type: str) -> None:
    message = filled(msgs.ROS_TYPES[ros_type], itertools.count(1))
    data = message.serialize()
    assert data[:2] == b"\x00\x01"  # CDR little-endian (XCDR1), as ROS 2 writes
    decoded = STORES["humble"].deserialize_cdr(data, ros_type)
    assert_same(message, decoded, ros_type)
    # and back: rosbags' bytes decode in the binding to the same message
    again = msgs.ROS_TYPES[ros_type].deserialize(STORES["humble"].serialize_cdr(decoded, ros_type))
    assert_same(again, message, ros_type)
