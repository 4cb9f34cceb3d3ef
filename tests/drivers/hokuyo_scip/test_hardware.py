"""On a real UTM-30LX (skipped unless one is attached: VIPSM_SCANNER_URL or /dev/hokuyo)."""

from __future__ import annotations

import numpy as np
import pytest

from drivers.hokuyo_scip.client import ClientConfig, Utm30lxClient
from tests.conftest import hardware_url


@pytest.mark.hardware
def test_real_scanner_info_scan_and_stream() -> None:
    with Utm30lxClient(hardware_url("scanner"), ClientConfig()) as c:
        p = c.info.params
        assert p.ares > 0 and p.amax > p.amin and c.info.version.protocol == "SCIP 2.0"
        scan = c.get_scan()
        assert scan.ranges_m.size == p.n_steps
        valid = scan.ranges_m[scan.valid]
        assert valid.size and (valid >= p.dmin_mm / 1000).all() and (valid <= p.dmax_mm / 1000).all()
        c.start_stream(intensity=True)
        scans = [c.next_scan(timeout_s=2.0) for _ in range(40)]
        c.stop_stream()
        assert all(s.intensities is not None for s in scans)
        assert (np.diff([s.device_stamp_ms for s in scans]) > 0).all()
        assert c.stats.corrupted_frames == 0
