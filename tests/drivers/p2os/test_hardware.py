"""Against a real Pioneer (skipped unless one is attached: VIPSM_ROBOT_URL or /dev/pioneer).

These tests never enable the motors: they check the handshake, the CONFIGpac, the SIP stream and a
clean close, which is what can be verified without supervising a moving robot.
"""

from __future__ import annotations

import math

import pytest

from drivers.p2os.client import ArcosClient, ArcosClientConfig
from tests.conftest import hardware_url

pytestmark = pytest.mark.hardware


def test_real_robot_handshake_stream_and_clean_close() -> None:
    url = hardware_url("robot")
    client = ArcosClient(ArcosClientConfig(url=url, enable_motors=False, reconnect=False, sip_silence_timeout_s=8.0))
    info = client.connect()
    try:
        assert info.robot_class.lower() == "pioneer"
        assert info.subclass  # selects the conversion table; an unknown one would have raised
        samples = [client.get_sample(5.0) for _ in range(20)]
        for _ in range(20):
            client.heartbeat()
            samples.append(client.get_sample(5.0))
    finally:
        client.close()
    assert client.close_confirmed is True
    seqs = [s.seq for s in samples]
    assert seqs == list(range(seqs[0], seqs[0] + len(seqs)))
    assert all(5.0 < s.battery_v < 16.0 for s in samples)
    # standing still: the odometry must not drift
    assert math.hypot(samples[-1].x_m, samples[-1].y_m) < 0.002
    if info.config is not None:
        assert info.config.values.get("sip_cycle_ms", 100) > 0
