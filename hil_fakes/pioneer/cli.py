"""``vipsm-robot fake robot``: serving the fake Pioneer on a pty or TCP, its command-line options."""

from __future__ import annotations

import argparse
import signal

from ..transport import DeviceServer, PtyEndpoint, TcpEndpoint, wait_forever
from ..wheel_odometry import OdometryNoise
from .model import _BAUDS, FakePioneer, PioneerConfig
from .protocol import DIST_CONV_MM

# ---------------------------------------------------------------------------------------------
# serving


def serve(model: FakePioneer, *, tcp: str | None = None, pty: bool = False, link: str | None = None) -> DeviceServer:
    """Start a fake on ``tcp`` (``HOST:PORT``) or a pty (optionally behind ``link``)."""
    if tcp is not None:
        host, _, port = tcp.rpartition(":")
        endpoint: TcpEndpoint | PtyEndpoint = TcpEndpoint(host or "127.0.0.1", int(port))
    elif pty:
        endpoint = PtyEndpoint(link)
        model.line_baud = lambda: pty_line_baud(endpoint)
    else:
        raise ValueError("serve needs tcp=HOST:PORT or pty=True")
    return DeviceServer(model, endpoint).start()


_ARCOS_RATES = (9600, 19200, 38400, 57600, 115200)


def pty_line_baud(endpoint: PtyEndpoint) -> int | None:
    """The rate the host set on its end of a pty; None when it is closed or the rate is not an ARCOS one."""
    bps = endpoint.line_speed_bps()
    return bps if bps in _ARCOS_RATES else None


def add_arguments(parser: argparse.ArgumentParser) -> None:
    where = parser.add_mutually_exclusive_group(required=True)
    where.add_argument("--tcp", metavar="HOST:PORT", help="serve on loopback TCP, e.g. 127.0.0.1:8101")
    where.add_argument("--pty", action="store_true", help="serve on a pseudo-terminal")
    parser.add_argument("--link", metavar="PATH", help="with --pty: stable symlink to the pty (like /dev/pioneer)")
    parser.add_argument("--name", default="fakebot")
    parser.add_argument("--subclass", default="p3dx", choices=sorted(DIST_CONV_MM))
    parser.add_argument("--sip-cycle-s", type=float, default=0.1)
    parser.add_argument("--watchdog-s", type=float, default=2.0)
    parser.add_argument("--no-watchdog-resume", action="store_true", help="stay stopped after a watchdog stop")
    parser.add_argument("--motors-enabled", action="store_true", help="start with motors enabled (AMRISim-like)")
    parser.add_argument("--start-x-counts", type=int, default=0, help="raw X at power-up (15-bit counter)")
    parser.add_argument("--start-y-counts", type=int, default=0)
    parser.add_argument("--start-th-units", type=int, default=0, help="raw heading at power-up (4096ths)")
    parser.add_argument("--heading-signed", action="store_true", help="send THPOS as -2048..2047")
    parser.add_argument("--sigma-trans-frac", type=float, default=0.0, help="odometry distance noise per metre")
    parser.add_argument("--sigma-rot-rad-per-m", type=float, default=0.0)
    parser.add_argument("--scale-error", type=float, default=0.0)
    parser.add_argument("--seed", type=int, default=None)
    parser.add_argument("--start-open", action="store_true", help="start with a stale open session")
    parser.add_argument("--junk-every", type=int, default=0, help="junk before every N-th SIP")
    parser.add_argument(
        "--host-baud",
        type=int,
        default=9600,
        choices=sorted(_BAUDS.values()),
        help="the controller's FLASH host rate (a pty client at another rate sees noise)",
    )
    parser.add_argument("--no-hostbaud", action="store_true", help="ignore HOSTBAUD (stay at --host-baud)")


def config_from_args(args: argparse.Namespace) -> PioneerConfig:
    return PioneerConfig(
        name=args.name,
        subclass=args.subclass,
        sip_cycle_s=args.sip_cycle_s,
        watchdog_s=args.watchdog_s,
        watchdog_resume=not args.no_watchdog_resume,
        motors_enabled_at_start=args.motors_enabled,
        start_x_counts=args.start_x_counts,
        start_y_counts=args.start_y_counts,
        start_th_units=args.start_th_units,
        heading_signed=args.heading_signed,
        odometry_noise=OdometryNoise(
            scale_error=args.scale_error,
            sigma_trans_frac=args.sigma_trans_frac,
            sigma_rot_rad_per_m=args.sigma_rot_rad_per_m,
            seed=args.seed,
        ),
        start_open=args.start_open,
        host_baud=args.host_baud,
        hostbaud_supported=not args.no_hostbaud,
    )


def run_from_args(args: argparse.Namespace) -> int:
    model = FakePioneer(config_from_args(args))
    if args.junk_every:
        model.junk_before_sips(args.junk_every)
    server = serve(model, tcp=args.tcp, pty=args.pty, link=args.link)

    def on_sigterm(signum: int, frame: object) -> None:
        raise KeyboardInterrupt

    previous = signal.signal(signal.SIGTERM, on_sigterm)
    try:
        print(server.address, flush=True)
        wait_forever([server])  # stops the server (and removes a --link) on Ctrl-C or SIGTERM
    except KeyboardInterrupt:
        pass  # the signal came before wait_forever was listening
    finally:
        signal.signal(signal.SIGTERM, previous)
        server.stop()  # idempotent; covers the early-signal case
    return 0
