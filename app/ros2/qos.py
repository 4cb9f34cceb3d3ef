"""ROS 2's QoS profiles as Cyclone DDS QoS, and the ROS 2 name of each topic on DDS.

* sensor data (``rmw_qos_profile_sensor_data``): best effort, volatile, keep last 5: ``/scan``;
* default (``rmw_qos_profile_default``): reliable, volatile, keep last 10: every other topic
  except tf's;
* ``/tf`` as tf2_ros's ``DynamicBroadcasterQoS``: reliable, volatile, keep last 100;
* ``/tf_static`` as tf2_ros's ``StaticBroadcasterQoS``: reliable, transient local, keep last 1 (one
  message holding every static transform, so a late subscriber gets them all).

A reliable writer is matched by reliable and best-effort readers alike; a best-effort one only by
best-effort readers, which is why ``ros2 topic echo /scan`` needs ``--qos-profile sensor_data``
(rviz2 picks it by itself). The writer's blocking time (a reliable writer whose history holds
unacknowledged data) is bounded and spent on the publisher's thread, never on the control loop's.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from ..errors import ConfigError

#: the longest a reliable write may wait for a slow reader before the sample is given up
MAX_BLOCKING_S = 0.05

_NAME_TOKEN = re.compile(r"[A-Za-z][A-Za-z0-9_]*")


@dataclass(frozen=True)
class Profile:
    """One ROS 2 QoS profile (the four policies ROS 2 sets; the rest are DDS defaults, as in ROS)."""

    reliable: bool
    transient_local: bool
    depth: int

    def dds_qos(self) -> object:
        from cyclonedds.qos import Policy, Qos
        from cyclonedds.util import duration

        reliability = (Policy.Reliability.Reliable(duration(seconds=MAX_BLOCKING_S)) if self.reliable
                       else Policy.Reliability.BestEffort)
        durability = Policy.Durability.TransientLocal if self.transient_local else Policy.Durability.Volatile
        return Qos(reliability, durability, Policy.History.KeepLast(self.depth),
                   Policy.DataRepresentation(use_cdrv0_representation=True))


SENSOR_DATA = Profile(reliable=False, transient_local=False, depth=5)
DEFAULT = Profile(reliable=True, transient_local=False, depth=10)
TF = Profile(reliable=True, transient_local=False, depth=100)
TF_STATIC = Profile(reliable=True, transient_local=True, depth=1)


def normalise_namespace(namespace: str) -> str:
    """A ROS namespace as ``/a/b`` ('' for none); ConfigError names ``ros2.namespace`` otherwise."""
    text = namespace.strip()
    if text in ("", "/"):
        return ""
    tokens = text.strip("/").split("/")
    if text.endswith("/") or "//" in text or not all(_NAME_TOKEN.fullmatch(tok) for tok in tokens):
        raise ConfigError("ros2.namespace", f"{namespace!r} is not a ROS namespace: tokens of letters, digits and "
                                            "'_' (not starting with a digit) separated by '/', e.g. /robot1")
    return "/" + "/".join(tokens)


def dds_topic(namespace: str, name: str) -> str:
    """The DDS topic of a ROS 2 topic: ``rt`` + namespace + name (``/scan`` in ``/r1`` -> ``rt/r1/scan``)."""
    return "rt" + normalise_namespace(namespace) + name
