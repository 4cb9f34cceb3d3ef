"""The fake UTM-30LX's configuration (identity, parameters, unverified behaviour) and the records of
its measuring state (a stream, a pending single scan), with the protocol's constants."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Utm30lxConfig:
    """Identity, parameters and unverified behaviour of the fake ([?] = not verified on hardware)."""

    vendor: str = "Hokuyo Automatic Co.,Ltd."
    product: str = "SOKUIKI Sensor TOP-URG UTM-30LX"
    firmware: str = "P.1.05(17/Apr./2009)"
    protocol: str = "SCIP 2.0"
    serial: str = "00903971"
    model: str = "UTM-30LX(Hokuyo Automatic Co.,Ltd.)"
    dmin_mm: int = 23
    dmax_mm: int = 60000
    ares: int = 1440
    amin: int = 0
    amax: int = 1080
    afrt: int = 540
    scan_rpm: int = 2400
    motor_speed_text: str = "Initial(2400[rpm])<-Default setting by user"
    measurement_mode: str = "CLASSIC"
    bit_rate_text: str = "USB Full Speed"
    status_text: str = "Sensor works well."
    #: the 24-bit ms counter at the moment the model first sees its clock (the recording's first II: 4821456)
    initial_time_ms: int = 4821456
    #: the recorded sensor had its laser on when the session began (BM answered 02) [? after power-up]
    laser_on_at_start: bool = True
    #: delay before a command's reply goes out (the real one answered after 3-25 ms) [?]
    reply_latency_s: float = 0.0
    #: status for any command other than TM while in time-adjust mode [?: urg_library expects 0E]
    time_mode_refusal: str = "0E"
    #: HS answer; "not supported on all UTM-30LX versions" [?]
    hs_status: str = "03"
    #: status for a known command with the wrong number of parameter characters [?: 0C or 0F]
    missing_parameter_status: str = "0C"
    #: some older firmware summed the II SCSP line only up to '<-' (P.1.05 sums all of it) [PEER]
    ii_sum_before_arrow: bool = False
    #: the sensor's ms counter runs this much fast (+) or slow (-) against the host clock
    clock_drift_ppm: float = 0.0
    #: bytes per second the link carries to the host: a message reaches the host when its last byte
    #: has crossed, after the ones queued before it (0: at once). USB Full Speed CDC-ACM: the recorded
    #: session's 6717-byte ME frame came in runs of 0.84-0.85 MB/s (theoretical bulk maximum 1.216
    #: MB/s) [DEV: one session; a host controller or hub may differ]; a 1081-step MD frame (3.4 kB)
    #: takes about 4 ms
    link_bytes_per_s: float = 840_000.0

    @property
    def scan_period_s(self) -> float:
        return 60.0 / self.scan_rpm

    @property
    def step_dt_s(self) -> float:
        return self.scan_period_s / self.ares


@dataclass
class _Stream:
    command: str  # MD / MS / ME
    params_prefix: str  # start+end+cluster+interval (11 chars)
    start: int
    end: int
    cluster: int
    interval: int
    count: int  # 0 = until QT
    remaining: int
    tag: str
    first_scan: int
    sent: int = 0


@dataclass
class _PendingSingle:
    echo: bytes
    command: str
    start: int
    end: int
    cluster: int
    not_before_scan: int


_SS_RATES = frozenset({"019200", "038400", "057600", "115200", "250000", "500000", "750000"})


_TAG_CHARS = frozenset("ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789 ._+@")


_MAX_CATCH_UP_SCANS = 8

#: a sweep is measured in this many parts, each as soon as its beams' times have passed, so a sweep's
#: data are ready when it ends, as on the sensor, instead of being computed all at once then
_SWEEP_PARTS = 4
