"""A ROS 2-style listener for the daemon's topics, without ROS (``vipsm-robot ros2-listen``): one
reader per topic with ROS 2's QoS, counting what arrives. It checks from another machine that the
robot is seen (domain, namespace, Cyclone config as the daemon's ``ros2.*``) and gives the bench a
subscriber, so DDS really sends.

Per topic: samples, rate, the writer's type name, and the age at receipt (receipt wall time minus
the header stamp: for ``/scan`` the sweep, the transfer and the loop's wait; for the estimate's
topics also the estimator's time; clocks of two machines add their offset).
"""

from __future__ import annotations

import statistics
import threading
import time
import typing

from . import qos
from .publisher import TOPICS

#: ages kept per topic for the median and 99th percentile (bounded)
MAX_AGES = 20_000


def _stamp_s(sample: typing.Any) -> float | None:
    h = getattr(sample, "header", None)
    if h is None:  # TFMessage, MarkerArray: the first element's
        items = getattr(sample, "transforms", None) or getattr(sample, "markers", None)
        h = items[0].header if items else None
    return None if h is None else h.stamp.sec + h.stamp.nanosec * 1e-9


def _quantile(values: list[float], q: float) -> float | None:
    if not values:
        return None
    s = sorted(values)
    return s[min(len(s) - 1, int(q * len(s)))]


def listen(namespace: str, domain_id: int, config_uri: str | None, duration_s: float, stop: threading.Event,
           on_ready: typing.Callable[[], None] | None = None) -> dict[str, typing.Any]:
    """Reads every topic for ``duration_s`` (or until ``stop``); a DDS error propagates (a CLI error)."""
    from cyclonedds.domain import Domain, DomainParticipant
    from cyclonedds.internal import InvalidSample
    from cyclonedds.sub import DataReader
    from cyclonedds.topic import Topic

    from .msgs import ROS_TYPES

    domain = Domain(domain_id, config_uri) if config_uri else None
    participant = DomainParticipant(domain_id)
    readers = {}
    for name, (ros_type, profile) in TOPICS.items():
        topic = Topic(participant, qos.dds_topic(namespace, name), ROS_TYPES[ros_type])
        readers[name] = DataReader(participant, topic, qos=profile.dds_qos())
    counts = dict.fromkeys(TOPICS, 0)
    ages: dict[str, list[float]] = {name: [] for name in TOPICS}
    first: dict[str, float] = {}
    last: dict[str, float] = {}
    types: dict[str, str] = {}
    if on_ready is not None:
        on_ready()
    end = time.monotonic() + duration_s
    while time.monotonic() < end and not stop.is_set():
        for name, reader in readers.items():
            for sample in reader.take(N=256):
                if isinstance(sample, InvalidSample):
                    continue
                now = time.time()
                counts[name] += 1
                first.setdefault(name, now)
                last[name] = now
                stamp = _stamp_s(sample)
                if stamp is not None and len(ages[name]) < MAX_AGES:
                    ages[name].append(now - stamp)
                if name not in types:
                    types[name] = type(sample).__idl_typename__
        stop.wait(0.005)
    del readers, participant, domain
    return {"namespace": namespace or "/", "domain_id": domain_id, "topics": {
        name: {
            "samples": counts[name],
            "rate_hz": round((counts[name] - 1) / (last[name] - first[name]), 2)
            if counts[name] > 1 and last[name] > first[name] else None,
            "type": types.get(name),
            "age_ms_median": None if not ages[name] else round(1e3 * statistics.median(ages[name]), 2),
            "age_ms_p99": None if not ages[name] else round(1e3 * _quantile(ages[name], 0.99), 2),  # type: ignore[operator]
        }
        for name in TOPICS
    }}
