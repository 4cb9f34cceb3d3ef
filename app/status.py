"""Modbus TCP status server (pymodbus): the daemon's state as input registers, and a stop coil.

Unit id 1 (any unit id is answered). All values are 16-bit registers; 32-bit values take two
registers, high word first. Signed values are two's complement. The map is documented in the
README ("Status registers") and is part of the product's interface: keep it stable.

Input registers (function code 4):

=====  ====================  ======  ===============================================================
addr   name                  type    meaning (unit)
=====  ====================  ======  ===============================================================
0      status_bits           uint16  bit0 scanner ok, bit1 base ok, bit2 camera ok, bit3 plain PSM
                                     (no camera), bit4 safety stop active, bit5 stop coil active,
                                     bit6 odometry fallback this cycle, bit7 loop healthy,
                                     bit8 simulated run, bit9 field-log error, bit10 protective
                                     field holds the robot, bit11 overloaded (the estimator cannot
                                     keep up with the scans: obstacles at a lower rate),
                                     bit12 ROS 2 publisher failed or a write failed (``ros2.*``),
                                     bit13 live view cannot accept viewers (``live.*``)
1      mission_state         uint16  0 hold, 1 moving, 2 safety stop, 3 device stop, 4 coil stop,
                                     5 protective stop (something in the path)
2-3    cycle                 uint32  control cycles run
4-5    pose_x_mm             int32   matched pose x (mm, odometry frame of the first scan)
6-7    pose_y_mm             int32   matched pose y (mm)
8      pose_theta_mrad       int16   matched heading (mrad, -3142..3142)
9      pose_sigma_mm         uint16  sqrt of the larger positional covariance eigenvalue (mm)
10     obstacle_count        uint16  obstacles tracked (all, even beyond the four listed)
11     reserved              uint16  0
12+8i  obstacle i (i=0..3):  id uint16, x_mm int32, y_mm int32, vx_mmps int16, vy_mmps int16,
                             radius_mm uint16 (unused slots all 0, id 0)
44     compute_10us          uint16  last cycle's compute time (10 us units)
45     jitter_p99_10us       uint16  period jitter p99 over the last 600 cycles (10 us units)
46     deadline_misses       uint16  cycles that overran their deadline (saturates at 65535)
47     log_dropped           uint16  field-log messages dropped (saturates)
48     scanner_state         uint16  0 absent, 1 connecting, 2 ok, 3 stalled, 4 failed
49     base_state            uint16  same codes
50     camera_state          uint16  same codes
51     battery_dv            uint16  base battery (0.1 V)
52     field_length_mm       uint16  protective field's reach ahead of the robot's origin (mm; 0 = not
                                     judged: field off, hold mode, no fresh scan yet)
53     field_nearest_mm      uint16  nearest confirmed return in the field, ahead of the origin (mm;
                                     0 = clear)
54     estimate_every        uint16  obstacles from every n-th scan (timer: period); 1 = all, more
                                     while overloaded
=====  ====================  ======  ===============================================================

Coil 0 (function codes 1, 5, 15): stop the base while set. Writes are honoured only when the config
enables it (``status.allow_stop_coil``); otherwise they are refused with Modbus exception 1
(illegal function) and nothing changes.

Function codes answered: the reads 1, 2, 3, 4, the coil writes 5 and 15 (as above) and Report
Server ID (17, the server's identification: ``vipsm-robot``). Every other function code is answered
with exception 1 (illegal function) and changes nothing: the holding-register writes (6, 16, 22,
23), the diagnostics (7 read exception status, 8 diagnostics including force listen-only mode,
11/12 communication event counter/log), the file records and FIFO queue (20, 21, 24), encapsulated
interfaces (43, including Read Device Identification: FC 17 already identifies the server) and any
code pymodbus does not know.
"""

from __future__ import annotations

import asyncio
import contextlib
import ipaddress
import logging
import math
import struct
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from pymodbus.constants import ExcCodes
from pymodbus.pdu import ExceptionResponse, ModbusPDU
from pymodbus.pdu.bit_message import WriteSingleCoilRequest
from pymodbus.pdu.other_message import ReportDeviceIdResponse
from pymodbus.server import ModbusTcpServer
from pymodbus.simulator import DataType, SimData, SimDevice

from .errors import AppError

N_INPUT_REGISTERS = 55
#: write single register, write multiple registers, mask write, read/write multiple: all refused
HOLDING_WRITE_FUNCTIONS = (6, 16, 22, 23)
#: the function codes a status server answers (reads, the stop coil, identification); all others are
#: refused with exception 1 before pymodbus acts on them
ANSWERED_FUNCTIONS = frozenset({1, 2, 3, 4, 5, 15, 17}) | frozenset(HOLDING_WRITE_FUNCTIONS)
#: what Report Server ID (FC 17) answers, instead of the library's name
SERVER_ID = b"vipsm-robot"
MAX_OBSTACLES = 4

DEVICE_STATES = {"absent": 0, "connecting": 1, "ok": 2, "stalled": 3, "failed": 4}
MISSION_STATES = {"hold": 0, "moving": 1, "safety_stop": 2, "device_stop": 3, "coil_stop": 4, "protective_stop": 5}
STATUS_BITS = {
    "scanner_ok": 0,
    "base_ok": 1,
    "camera_ok": 2,
    "plain_psm": 3,
    "safety_stop": 4,
    "coil_stop": 5,
    "odometry_fallback": 6,
    "loop_healthy": 7,
    "simulated": 8,
    "log_error": 9,
    "protective_stop": 10,
    "overloaded": 11,
    "ros2_error": 12,
    "live_view_error": 13,
}


@dataclass(frozen=True)
class ObstacleStatus:
    track_id: int
    x_m: float
    y_m: float
    vx_mps: float
    vy_mps: float
    radius_m: float


@dataclass(frozen=True)
class StatusSnapshot:
    cycle: int = 0
    flags: frozenset[str] = frozenset()
    mission_state: str = "hold"
    x_m: float = 0.0
    y_m: float = 0.0
    theta_rad: float = 0.0
    sigma_m: float = 0.0
    obstacles: tuple[ObstacleStatus, ...] = ()
    compute_s: float = 0.0
    jitter_p99_s: float = 0.0
    deadline_misses: int = 0
    log_dropped: int = 0
    scanner_state: str = "absent"
    base_state: str = "absent"
    camera_state: str = "absent"
    battery_v: float = 0.0
    field_length_m: float = 0.0
    field_nearest_m: float = 0.0
    estimate_every: float = 1.0
    extra: dict[str, float] = field(default_factory=dict)


def _u16(v: float) -> int:
    return int(min(max(round(v), 0), 0xFFFF))


def _i16(v: float) -> int:
    return int(min(max(round(v), -0x8000), 0x7FFF)) & 0xFFFF


def _i32(v: float) -> list[int]:
    x = int(min(max(round(v), -0x80000000), 0x7FFFFFFF)) & 0xFFFFFFFF
    return [x >> 16, x & 0xFFFF]


def _u32(v: int) -> list[int]:
    x = int(min(max(v, 0), 0xFFFFFFFF))
    return [x >> 16, x & 0xFFFF]


def encode_registers(s: StatusSnapshot) -> list[int]:
    """The input-register image of a snapshot (see the module doc for the map)."""
    regs = [0] * N_INPUT_REGISTERS
    bits = 0
    for name in s.flags:
        if name not in STATUS_BITS:
            raise AppError(f"unknown status flag {name!r}")
        bits |= 1 << STATUS_BITS[name]
    regs[0] = bits
    regs[1] = MISSION_STATES[s.mission_state]
    regs[2:4] = _u32(s.cycle)
    regs[4:6] = _i32(s.x_m * 1000.0)
    regs[6:8] = _i32(s.y_m * 1000.0)
    theta = math.atan2(math.sin(s.theta_rad), math.cos(s.theta_rad))
    regs[8] = _i16(theta * 1000.0)
    regs[9] = _u16(s.sigma_m * 1000.0)
    regs[10] = _u16(len(s.obstacles))
    for i, ob in enumerate(s.obstacles[:MAX_OBSTACLES]):
        base = 12 + 8 * i
        regs[base] = _u16(ob.track_id)
        regs[base + 1 : base + 3] = _i32(ob.x_m * 1000.0)
        regs[base + 3 : base + 5] = _i32(ob.y_m * 1000.0)
        regs[base + 5] = _i16(ob.vx_mps * 1000.0)
        regs[base + 6] = _i16(ob.vy_mps * 1000.0)
        regs[base + 7] = _u16(ob.radius_m * 1000.0)
    regs[44] = _u16(s.compute_s * 1e5)
    regs[45] = _u16(s.jitter_p99_s * 1e5)
    regs[46] = _u16(s.deadline_misses)
    regs[47] = _u16(s.log_dropped)
    regs[48] = DEVICE_STATES[s.scanner_state]
    regs[49] = DEVICE_STATES[s.base_state]
    regs[50] = DEVICE_STATES[s.camera_state]
    regs[51] = _u16(s.battery_v * 10.0)
    regs[52] = _u16(s.field_length_m * 1000.0)
    regs[53] = _u16(s.field_nearest_m * 1000.0)
    regs[54] = _u16(s.estimate_every)
    return regs


def decode_int32(hi: int, lo: int) -> int:
    x = (hi << 16) | lo
    return x - 0x100000000 if x & 0x80000000 else x


def _own_server_id(sending: bool, pdu: ModbusPDU) -> ModbusPDU:
    """Report Server ID (FC 17) answers with the product's name, never the library's."""
    if sending and isinstance(pdu, ReportDeviceIdResponse):
        pdu.identifier = SERVER_ID
    return pdu


#: how often the supervisor closes idle connections and checks the listener
SUPERVISE_S = 0.5


def exposure_warning(host: str, allow_stop_coil: bool) -> str:
    """A warning when the registers (and maybe the stop coil) are reachable from other hosts; '' if not."""
    try:
        loopback = host == "localhost" or ipaddress.ip_address(host).is_loopback
    except ValueError:
        loopback = False  # a host name: it may resolve to any interface
    if loopback:
        return ""
    coil = "and the stop coil is honoured" if allow_stop_coil else "(stop coil writes refused)"
    return f"status.host = {host!r}: the Modbus status registers are reachable from the network {coil}"


class _GuardedServer(ModbusTcpServer):
    """pymodbus's TCP server with a cap on concurrent connections and an idle timeout per connection
    (a client that connects and says nothing, or too many at once, cannot hold the port)."""

    def __init__(self, *args: Any, max_connections: int, idle_timeout_s: float, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.max_connections = max_connections
        self.idle_timeout_s = idle_timeout_s
        self.refused_connections = 0
        self.idle_closed = 0

    def callback_new_connection(self) -> Any:
        handler = super().callback_new_connection()
        handler.last_rx_s = time.monotonic()
        refuse = len(self.active_connections) >= self.max_connections
        on_data, on_made = handler.callback_data, handler.connection_made

        def callback_data(data: bytes, addr: tuple | None = None) -> int:  # type: ignore[type-arg]
            handler.last_rx_s = time.monotonic()
            return int(on_data(data, addr))

        def connection_made(transport: asyncio.BaseTransport) -> None:
            on_made(transport)
            if refuse:
                self.refused_connections += 1
                handler.close()

        handler.callback_data, handler.connection_made = callback_data, connection_made
        return handler

    def close_idle(self, now_s: float) -> None:
        for handler in list(self.active_connections.values()):
            if now_s - getattr(handler, "last_rx_s", now_s) > self.idle_timeout_s:
                self.idle_closed += 1
                handler.close()

    def listening(self) -> bool:
        server = self.transport
        return server is not None and bool(getattr(server, "is_serving", lambda: True)())


class StatusServer:
    """Serves the registers on its own thread (an asyncio loop); ``publish`` never blocks.

    A supervisor task closes connections idle for ``idle_timeout_s``, and restarts the listener if it
    stops listening (reported through ``on_event`` and counted in ``restarts``)."""

    def __init__(self, host: str = "127.0.0.1", port: int = 5020, allow_stop_coil: bool = False,
                 max_connections: int = 8, idle_timeout_s: float = 30.0) -> None:
        self.host = host
        self.port = port
        self.allow_stop_coil = allow_stop_coil
        self.max_connections = max_connections
        self.idle_timeout_s = idle_timeout_s
        #: listener restarts after it stopped listening, and the last reason
        self.restarts = 0
        self.last_failure: str | None = None
        self.on_event: Callable[[str, str], None] | None = None
        self._regs = [0] * N_INPUT_REGISTERS
        self._stop_coil = False
        self._lock = threading.Lock()
        self._loop: asyncio.AbstractEventLoop | None = None
        self._server: ModbusTcpServer | None = None
        self._thread: threading.Thread | None = None
        self._ready = threading.Event()
        self._stopping = False
        self.error: BaseException | None = None
        #: coil writes refused because the config does not allow them
        self.refused_writes = 0
        #: requests refused because their function code is not one a status server answers
        self.refused_functions = 0
        # pymodbus logs every junk frame a client sends at ERROR level (">>>>> recv ...", "Invalid Modbus
        # protocol id"): a remote client could flood the journal. Start failures still surface as
        # exceptions (start() raises AppError).
        logging.getLogger("pymodbus").setLevel(logging.CRITICAL + 1)

    @property
    def stop_requested(self) -> bool:
        with self._lock:
            return self._stop_coil

    def publish(self, snapshot: StatusSnapshot) -> None:
        regs = encode_registers(snapshot)
        with self._lock:
            self._regs = regs

    async def _action(
        self,
        function_code: int,
        start_address: int,
        address: int,
        count: int,
        current_registers: list[int],
        set_values: list[int] | list[bool] | None,
    ) -> ExcCodes | None:
        if function_code == 4:
            with self._lock:
                regs = self._regs
            for i in range(len(current_registers)):
                a = start_address + i
                current_registers[i] = regs[a] if 0 <= a < len(regs) else 0
        elif function_code in HOLDING_WRITE_FUNCTIONS:
            self.refused_writes += 1  # nothing here is writable but the stop coil
            return ExcCodes.ILLEGAL_FUNCTION
        elif function_code in (5, 15) and set_values is not None:
            if not self.allow_stop_coil:
                self.refused_writes += 1
                return ExcCodes.ILLEGAL_FUNCTION
            if address <= 0 < address + len(set_values):
                with self._lock:
                    self._stop_coil = bool(set_values[0 - address])
        elif function_code == 1:
            with self._lock:
                coil = self._stop_coil
            if current_registers:
                current_registers[0] = int(coil)
        return None

    def _device(self) -> SimDevice:
        return SimDevice(
            0,
            simdata=(
                [SimData(0, count=16, values=False, datatype=DataType.BITS)],
                [SimData(0, count=16, values=False, datatype=DataType.BITS)],
                [SimData(0, count=1, values=0, datatype=DataType.REGISTERS)],
                [SimData(0, count=N_INPUT_REGISTERS, values=0, datatype=DataType.REGISTERS)],
            ),
            action=self._action,
        )

    def start(self, timeout_s: float = 5.0) -> StatusServer:
        def run() -> None:
            loop = asyncio.new_event_loop()
            self._loop = loop
            try:
                loop.run_until_complete(self._serve())
            except BaseException as exc:  # noqa: BLE001 - surfaced by start() and the daemon status
                self.error = exc
                self._ready.set()
            finally:
                loop.close()

        self._thread = threading.Thread(target=run, name="status-server", daemon=True)
        self._thread.start()
        if not self._ready.wait(timeout_s):
            raise AppError(f"status server on {self.host}:{self.port} did not start within {timeout_s} s")
        if self.error is not None:
            # pymodbus hides the OSError: name the usual cause (a second instance) and the settings
            hint = " (port in use by another instance? set status.port, 0 = any free port, or status.enabled = false)"
            raise AppError(f"status server on {self.host}:{self.port} failed: {self.error}{hint}")
        warning = exposure_warning(self.host, self.allow_stop_coil)
        if warning:
            print(f"vipsm-robot: warning: {warning}", file=sys.stderr, flush=True)
        return self

    async def _listen(self) -> asyncio.Future[Any]:
        """A new listener on (host, port); raises what pymodbus raised if it cannot listen."""
        self._server = _GuardedServer(self._device(), address=(self.host, self.port), trace_pdu=_own_server_id,
                                      custom_pdu=[self._strict_write_coil(), *self._refused_functions()],
                                      max_connections=self.max_connections, idle_timeout_s=self.idle_timeout_s)
        task = asyncio.ensure_future(self._server.serve_forever())
        for _ in range(200):
            if self._server.transport is not None or task.done():
                break
            await asyncio.sleep(0.01)
        if task.done() and task.exception() is not None:
            raise task.exception()  # type: ignore[misc]
        sockets = getattr(self._server.transport, "sockets", None) or []
        if self.port == 0 and sockets:
            self.port = int(sockets[0].getsockname()[1])  # a restart keeps the port clients know
        return task

    async def _serve(self) -> None:
        # the server must be built inside the running loop
        task = await self._listen()
        self._ready.set()
        while not self._stopping:
            await asyncio.sleep(SUPERVISE_S)
            assert self._server is not None
            self._server.close_idle(time.monotonic())
            if self._stopping or (self._server.listening() and not task.done()):
                continue
            task = await self._restart(task)

    async def _restart(self, task: asyncio.Future[Any]) -> asyncio.Future[Any]:
        reason = "stopped listening" if not task.done() or task.exception() is None else repr(task.exception())
        self.last_failure = reason
        self._event("error", f"status server on {self.host}:{self.port} {reason}; restarting it")
        with contextlib.suppress(Exception):
            assert self._server is not None
            await self._server.shutdown()
        try:
            task = await self._listen()
        except Exception as exc:  # noqa: BLE001 - retried at the next supervision tick
            self.last_failure = f"restart failed: {exc}"
            self._event("error", f"status server on {self.host}:{self.port}: {self.last_failure}")
            return task
        self.restarts += 1
        self._event("info", f"status server on {self.host}:{self.port} listening again")
        return task

    def _strict_write_coil(self) -> type[WriteSingleCoilRequest]:
        """Write Single Coil (FC 5) as the spec has it: only 0xFF00 (on) and 0x0000 (off). pymodbus
        turns any value into a bool when it decodes; this request keeps the value and answers any
        other with exception 3 (illegal data value), changing nothing, coil allowed or not."""
        server = self

        class StrictWriteSingleCoil(WriteSingleCoilRequest):
            raw_value = 0

            def decode(self, data: bytes) -> None:
                super().decode(data)
                self.raw_value = struct.unpack(">H", data[2:4])[0]

            async def datastore_update(self, context: Any, device_id: int) -> ModbusPDU:
                if self.raw_value not in (0x0000, 0xFF00):
                    server.refused_writes += 1
                    return ExceptionResponse(self.function_code, ExcCodes.ILLEGAL_VALUE)
                return await super().datastore_update(context, device_id)

        return StrictWriteSingleCoil

    def _refused_functions(self) -> list[type[ModbusPDU]]:
        """A request class for every function code not in ``ANSWERED_FUNCTIONS``: it takes any body and
        answers exception 1 (illegal function), counted in ``refused_functions``. Registered in place of
        pymodbus's own classes, so diagnostics (FC 8 force listen-only mode, ...) never reach them."""
        server = self

        class RefusedFunction(ModbusPDU):
            def decode(self, data: bytes) -> None:
                pass  # the body is not looked at: the function itself is refused

            async def datastore_update(self, context: Any, device_id: int) -> ModbusPDU:
                server.refused_functions += 1
                return ExceptionResponse(self.function_code, ExcCodes.ILLEGAL_FUNCTION)

        return [type(f"RefusedFunction{fc}", (RefusedFunction,), {"function_code": fc})
                for fc in range(1, 0x80) if fc not in ANSWERED_FUNCTIONS]

    def connection_counts(self) -> dict[str, int]:
        """Connections refused over the cap and closed for idleness (by the current listener), and requests
        refused for their function code (whole run)."""
        srv = self._server
        return {"refused_connections": srv.refused_connections if srv else 0,
                "idle_closed": srv.idle_closed if srv else 0, "refused_functions": self.refused_functions}

    def _event(self, level: str, message: str) -> None:
        if self.on_event is not None:
            self.on_event(level, message)
        else:
            print(f"vipsm-robot: {level}: {message}", file=sys.stderr, flush=True)

    def stop(self) -> None:
        if self._loop is None or self._server is None or self._thread is None:
            return
        self._stopping = True
        try:
            asyncio.run_coroutine_threadsafe(self._server.shutdown(), self._loop).result(5.0)
        except (RuntimeError, TimeoutError, OSError):
            pass
        self._thread.join(5.0)
        self._thread = None
