"""A ROS 2-style subscriber in its own process for ``test_ros2_e2e.py``: plain ``cyclonedds`` (the
Cyclone config and domain come from CYCLONEDDS_URI and ROS_DOMAIN_ID, as for a ROS 2 node), readers
with ROS 2's QoS on every topic the daemon publishes; ``/tf_static`` is read by a reader created only
after the first scan arrived, so its message must have been kept for late joiners (transient local).

Usage: ``python ros2_subscriber.py NAMESPACE OUT.json``; prints ``ready`` once its readers exist, then
collects until its stdin closes and writes what it saw as JSON.
"""

from __future__ import annotations

import dataclasses
import json
import os
import sys
import threading
import time

from cyclonedds.domain import DomainParticipant
from cyclonedds.internal import InvalidSample
from cyclonedds.qos import Policy
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic

from app.ros2 import msgs, qos
from app.ros2.publisher import TOPICS

KEEP = 3  # samples kept per topic: the first ones, and the newest in "last"


def plain(obj: object) -> object:
    if dataclasses.is_dataclass(obj):
        return {f.name: plain(getattr(obj, f.name)) for f in dataclasses.fields(obj)}
    if isinstance(obj, bytes):
        return {"bytes": len(obj), "head": obj[:4].hex()}
    if isinstance(obj, list):
        return [plain(v) for v in obj[:400]]
    if isinstance(obj, float) and obj != obj:
        return "nan"
    if isinstance(obj, float) and obj in (float("inf"), float("-inf")):
        return str(obj)
    return obj


def writer_qos(reader: DataReader) -> dict[str, object]:
    out: dict[str, object] = {}
    for handle in reader.get_matched_publications():
        ep = reader.get_matched_publication_data(handle)
        if ep is not None:
            out = {"type_name": ep.type_name, "topic_name": ep.topic_name,
                   **{key: str(ep.qos[policy]) for key, policy in
                      (("reliability", Policy.Reliability), ("durability", Policy.Durability),
                       ("history", Policy.History))}}
    return out


def main() -> int:
    namespace, out_path = sys.argv[1], sys.argv[2]
    participant = DomainParticipant(int(os.environ.get("ROS_DOMAIN_ID", "0")))
    readers: dict[str, DataReader] = {}

    def reader(name: str) -> DataReader:
        ros_type, profile = TOPICS[name]
        topic = Topic(participant, qos.dds_topic(namespace, name), msgs.ROS_TYPES[ros_type])
        return DataReader(participant, topic, qos=profile.dds_qos())

    for name in TOPICS:
        if name != "/tf_static":
            readers[name] = reader(name)
    seen: dict[str, dict[str, object]] = {name: {"count": 0, "samples": []} for name in TOPICS}
    closed = threading.Event()
    threading.Thread(target=lambda: (sys.stdin.read(), closed.set()), daemon=True).start()
    print("ready", flush=True)
    deadline = time.monotonic() + 120.0
    while not closed.is_set() and time.monotonic() < deadline:
        if "/tf_static" not in readers and seen["/scan"]["count"]:
            time.sleep(0.5)  # well after the publisher wrote its static transforms
            readers["/tf_static"] = reader("/tf_static")
        for name, r in readers.items():
            for sample in r.take(N=64):
                if isinstance(sample, InvalidSample):  # the writer went away: a state change, no data
                    continue
                entry = seen[name]
                entry["count"] = int(entry["count"]) + 1  # type: ignore[call-overload]
                if len(entry["samples"]) < KEEP:  # type: ignore[arg-type]
                    entry["samples"].append(plain(sample))  # type: ignore[union-attr]
                elif name != "/scan":  # the newest too (scans are many and large)
                    entry["last"] = plain(sample)
                entry["writer"] = writer_qos(r) or entry.get("writer", {})
                entry["last_wall_s"] = time.time()
        time.sleep(0.02)
    with open(out_path, "w", encoding="utf-8") as f:
        json.dump(seen, f)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
