"""`vipsm-robot` commands for the Pioneer 3-DX (ARCOS/P2OS): probe, drive, fake robot, bench.

* ``vipsm-robot probe --robot URL --json``: handshake, name/class/subclass, CONFIGpac values, one
  odometry sample; motors are not enabled; closes cleanly (VEL 0, RVEL 0, ENABLE 0, CLOSE)
* ``vipsm-robot drive --robot URL --v 0.2 --w 0.0 --seconds 3 --json``: enables the motors, drives
  at (v, w) for the given time (commanding at 10 Hz), stops, waits for rest, prints the final odometry
* ``vipsm-robot fake robot --tcp 127.0.0.1:8101`` or ``--pty [--link PATH]``: serve the fake until Ctrl-C
* ``vipsm-robot bench --only robot --json``: codec and odometry throughput

:func:`to_vipsm_odometry` turns a driver sample into the estimator's :class:`vipsm.types.Odometry`.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import time
from typing import Any

from drivers.p2os import codec
from drivers.p2os.client import ArcosClient, ArcosClientConfig
from drivers.p2os.odometry import OdometrySample, OdometryTracker, params_for_subclass
from vipsm.types import Odometry

from .cli import emit
from .errors import AppError

#: drive refuses faster commands unless --max-v / --max-w are raised (bench tests on a real robot)
DEFAULT_DRIVE_MAX_V_MPS = 0.5
DEFAULT_DRIVE_MAX_W_RADPS = math.radians(60.0)


def to_vipsm_odometry(sample: OdometrySample) -> Odometry:
    return Odometry(
        x_m=sample.x_m,
        y_m=sample.y_m,
        theta_rad=sample.theta_rad,
        v_mps=sample.v_mps,
        w_radps=sample.w_radps,
        stamp_s=sample.stamp_s,
    )


def sample_dict(sample: OdometrySample, *, sonar: bool = True) -> dict[str, Any]:
    out: dict[str, Any] = {
        "stamp_s": sample.stamp_s,
        "seq": sample.seq,
        "x_m": sample.x_m,
        "y_m": sample.y_m,
        "theta_rad": sample.theta_rad,
        "theta_deg": math.degrees(sample.theta_rad),
        "v_mps": sample.v_mps,
        "w_radps": sample.w_radps,
        "left_wheel_mps": sample.left_wheel_mps,
        "right_wheel_mps": sample.right_wheel_mps,
        "battery_v": sample.battery_v,
        "motors_enabled": sample.motors_enabled,
        "estop_pressed": sample.estop_pressed,
        "left_stall": sample.left_stall,
        "right_stall": sample.right_stall,
        "front_bumpers": sample.front_bumpers,
        "rear_bumpers": sample.rear_bumpers,
        "flags": sample.flags,
        "gap": sample.gap,
        "missed_cycles": sample.missed_cycles,
        "ambiguous": sample.ambiguous,
        "rebaselined": sample.rebaselined,
    }
    if sonar:
        out["sonars"] = [
            {
                "index": s.index,
                "range_m": s.range_m,
                "pose": None if s.pose is None else dataclasses.asdict(s.pose),
            }
            for s in sample.sonars
        ]
    return out


def _client_config(args: argparse.Namespace, **kw: Any) -> ArcosClientConfig:
    timeout_s = float(getattr(args, "timeout_s", 5.0) or 5.0)
    base: dict[str, Any] = {
        "url": args.robot,
        "baudrate": int(getattr(args, "baud", 9600) or 9600),
        "sync_step_timeout_s": max(0.2, min(1.0, timeout_s / 4)),
        "reconnect": False,
    }
    if getattr(args, "switch_baud", None):
        base["switch_baudrate"] = int(args.switch_baud)
    if getattr(args, "hunt_bauds", None):
        base["baud_candidates"] = tuple(int(b) for b in args.hunt_bauds.split(","))
    if getattr(args, "subclass_fallback", None):
        base["subclass_fallback"] = args.subclass_fallback
    base.update(kw)
    return ArcosClientConfig(**base)


def _info_dict(client: ArcosClient) -> dict[str, Any]:
    info = client.info
    return {
        "url": client.config.url,
        "name": info.name,
        "class": info.robot_class,
        "subclass": info.subclass,
        "baudrate": info.baudrate,
        "dist_conv_mm_per_count": info.params.dist_conv_mm_per_count,
        "angle_conv_rad_per_unit": info.params.angle_conv_rad_per_unit,
        "config": None if info.config is None else dict(info.config.values),
    }


def probe(args: argparse.Namespace) -> dict[str, Any]:
    """Handshake, CONFIG, one SIP; the motors stay disabled; close cleanly."""
    timeout_s = float(getattr(args, "timeout_s", 5.0) or 5.0)
    client = ArcosClient(_client_config(args, enable_motors=False))
    client.connect()
    try:
        out = _info_dict(client)
        out["odometry"] = sample_dict(client.get_sample(timeout_s))
    finally:
        client.close()
    out["closed_cleanly"] = client.close_confirmed
    out["checksum_errors"] = client.stats.checksum_errors
    return out


def _cmd_drive(args: argparse.Namespace) -> int:
    if not (math.isfinite(args.v) and math.isfinite(args.w) and args.seconds >= 0):
        raise AppError("drive needs finite --v/--w and --seconds >= 0")
    if abs(args.v) > args.max_v or abs(args.w) > args.max_w:
        raise AppError(
            f"refusing |v| > {args.max_v} m/s or |w| > {args.max_w} rad/s (raise --max-v/--max-w deliberately)"
        )
    client = ArcosClient(_client_config(args, enable_motors=True, command_timeout_s=0.5))
    client.connect()
    try:
        start = client.get_sample(args.timeout_s)
        end = time.monotonic() + args.seconds
        while time.monotonic() < end:
            client.set_velocity(args.v, args.w)
            time.sleep(min(0.1, max(0.0, end - time.monotonic())))
        client.set_velocity(0.0, 0.0)
        # wait (bounded) for the robot to come to rest, keeping the link alive
        deadline = time.monotonic() + args.settle_s
        final = client.get_sample(args.timeout_s)
        while time.monotonic() < deadline:
            client.heartbeat()
            final = client.get_sample(args.timeout_s)
            if abs(final.v_mps) < 1e-3 and abs(final.w_radps) < 1e-3:
                break
        at_rest = abs(final.v_mps) < 1e-3 and abs(final.w_radps) < 1e-3
        result = _info_dict(client)
        result.pop("config")
    finally:
        client.close()
    result.update(
        {
            "commanded": {"v_mps": args.v, "w_radps": args.w, "seconds": args.seconds},
            "start": sample_dict(start, sonar=False),
            "final": sample_dict(final, sonar=False),
            "at_rest": at_rest,
            "distance_m": math.hypot(final.x_m - start.x_m, final.y_m - start.y_m),
            "checksum_errors": client.stats.checksum_errors,
            "closed_cleanly": client.close_confirmed,
        }
    )
    emit(result, args.json)
    return 0 if at_rest else 1


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = sub.add_parser("drive", help="drive the Pioneer at (v, w) for a while, stop, print the final odometry")
    p.add_argument("--robot", required=True, metavar="URL", help="/dev/ttyUSB0, /dev/pioneer, socket://127.0.0.1:8101")
    p.add_argument("--v", type=float, default=0.0, help="translational velocity, m/s (+ forward)")
    p.add_argument("--w", type=float, default=0.0, help="rotational velocity, rad/s (+ counter-clockwise)")
    p.add_argument("--seconds", type=float, default=1.0, help="how long to drive")
    p.add_argument("--max-v", type=float, default=DEFAULT_DRIVE_MAX_V_MPS, help="refuse faster --v (m/s)")
    p.add_argument("--max-w", type=float, default=DEFAULT_DRIVE_MAX_W_RADPS, help="refuse faster --w (rad/s)")
    p.add_argument("--settle-s", type=float, default=5.0, help="wait at most this long for the robot to stop")
    p.add_argument("--timeout-s", type=float, default=5.0, help="per-sample timeout")
    p.add_argument("--baud", type=int, default=9600, help="serial rate (ignored on TCP)")
    p.add_argument("--switch-baud", type=int, help="switch the port to this rate with HOSTBAUD after CONFIG")
    p.add_argument("--hunt-bauds", metavar="RATES", help="if nothing answers, try these rates, e.g. 38400,19200")
    p.add_argument("--subclass-fallback", help="conversion table for an unknown subclass (p3dx or p3dx-sh)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=_cmd_drive)


def register_fake(fake_sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    from hil_fakes import pioneer

    p = fake_sub.add_parser("robot", help="fake Pioneer 3-DX (ARCOS) on a pty or loopback TCP")
    pioneer.add_arguments(p)
    p.set_defaults(func=pioneer.run_from_args)


# ------------------------------------------------------------------------------------ bench


def bench(args: argparse.Namespace) -> dict[str, Any]:
    """Decode and odometry throughput on synthetic full SIPs (16 sonars, ARCOS tail)."""
    import struct

    payload = bytearray(struct.pack("<BHHhhhBHhHBB", 0x33, 0, 0, 0, 200, 200, 125, 0, 0, 0x1F, 0, 16))
    for i in range(16):
        payload += struct.pack("<BH", i, 1000 + i)
    payload += bytes(5) + struct.pack("<HBhH", 125, 0, 0, 0)
    frames = []
    for k in range(2000):
        struct.pack_into("<H", payload, 1, (k * 7) & 0x7FFF)
        frames.append(codec.frame(bytes(payload)))
    wire = b"".join(frames)
    decoder = codec.ArcosDecoder()
    t0 = time.perf_counter()
    events = []
    for i in range(0, len(wire), 89):
        events += decoder.feed(wire[i : i + 89])
    t1 = time.perf_counter()
    sips = [e for e in events if isinstance(e, codec.Sip)]
    tracker = OdometryTracker(params_for_subclass("p3dx"))
    t2 = time.perf_counter()
    for k, s in enumerate(sips):
        tracker.update(s, k * 0.1)
    t3 = time.perf_counter()
    n = len(sips)
    out: dict[str, Any] = {
        "sips": n,
        "sip_bytes": len(frames[0]),
        "decode_us_per_sip": (t1 - t0) / n * 1e6,
        "odometry_us_per_sip": (t3 - t2) / n * 1e6,
        "cpu_share_at_10hz_percent": ((t1 - t0) + (t3 - t2)) / n * 10 * 100,
    }
    out.update(_bench_connect())
    return out


def _bench_connect(rounds: int = 3) -> dict[str, Any]:
    """Handshake + OPEN + CONFIG + first SIP against the in-process fake, median of ``rounds``."""
    from hil_fakes.pioneer import FakePioneer, serve

    result: dict[str, Any] = {}
    for kind in ("pty", "tcp"):
        times = []
        model = FakePioneer()
        server = serve(model, tcp="127.0.0.1:0") if kind == "tcp" else serve(model, pty=True)
        try:
            for _ in range(rounds):
                client = ArcosClient(ArcosClientConfig(url=server.address, enable_motors=False, reconnect=False))
                t0 = time.perf_counter()
                client.connect()
                client.get_sample(5.0)
                times.append(time.perf_counter() - t0)
                client.close()
        finally:
            server.stop()
        times.sort()
        result[f"connect_to_first_sample_s_{kind}"] = times[len(times) // 2]
    return result
