#!/usr/bin/python3
"""A third-party illuminator controller: docs/registers.md implemented with Debian's pymodbus
(3.0) serial server, written from that page alone (not from descatter's C code), so that
descatterd's Modbus backend meets a controller it was not built against.

It answers Modbus RTU on a serial device (one end of a socat pty pair; use --parity N there:
pyserial cannot set parity on a pty). With --light-port it
also serves the same registers read-only over Modbus TCP on 127.0.0.1: descatter-labsim's camera
reads the lit phase there (--light-from), standing in for the optics between projector and
camera.

The projector draws any period of 2.00 .. 655.35 px written to PERIOD_CENTIPX (CAPABILITIES
PERIOD_ADJUSTABLE), or with --fixed-period-centipx C only its own C; with --map-revision 1 it is a
controller of the first map, without CAPABILITIES .. PERIOD_MAX_CENTIPX.

Fault knobs, armed by signals so a test can place them between two phase sets. A signal is
handled between two requests, some time after it was sent: each knob prints a line once armed
("pymodbus-controller: armed busy", "pymodbus-controller: silent on|off"), and every request read
after that line gets the fault, so a test that waits for the line knows which requests do.
  SIGUSR1   the next --busy-count requests (default 12) get exception 06 (server busy)
  SIGUSR2   toggles silence: no answer at all until the next SIGUSR2

Prints "pymodbus-controller: ready rtu=DEVICE light=HOST:PORT" once serving; on SIGTERM prints
"pymodbus-controller: requests=R applies=A" and the last serial events (bytes read, requests and
what each got, knobs armed), with their times, to stderr, and exits 0: a test that fails on a
missing answer dies with SIGTERM to this process, so its log says whether the requests reached
the controller and what the controller did with them.
"""
import argparse
import asyncio
import collections
import logging
import os
import signal
import sys
import time

from pymodbus.datastore import ModbusServerContext
from pymodbus.framer.rtu_framer import ModbusRtuFramer
from pymodbus.pdu import ModbusExceptions
from pymodbus.register_read_message import ReadHoldingRegistersResponse, ReadInputRegistersResponse
from pymodbus.register_write_message import WriteMultipleRegistersResponse, WriteSingleRegisterResponse
from pymodbus.server.async_io import ModbusSerialServer, ModbusSingleRequestHandler, ModbusTcpServer

# docs/registers.md, "Holding registers" and "Input registers".
PHASE, ENABLE, NUM_PHASES, PATTERN_KIND, PERIOD_CENTIPX, DUTY_PERMILLE, BLACK_PERMILLE, INTENSITY_PERMILLE = range(8)
N_HOLDING = 8
MAGIC, FIRMWARE_VERSION, STATUS, APPLIED_PHASE, APPLY_COUNT, TEMPERATURE = range(6)
CAPABILITIES, PERIOD_MIN_CENTIPX, PERIOD_MAX_CENTIPX = range(6, 9)
PERIOD_ADJUSTABLE = 0x0001
READY, FAULT, OVER_TEMPERATURE, APPLYING, ENABLED = 0x01, 0x02, 0x04, 0x08, 0x10
PHASE_OFF = 0xFFFF


class Controller:
    """The device model: written registers, the pattern as lit, the settle time."""

    def __init__(self, settle_s, fixed_period, revision):
        self.settle_s = settle_s
        self.revision = revision
        self.n_input = 6 if revision == 1 else 9
        if fixed_period:
            self.capabilities, self.period_range = 0, (fixed_period, fixed_period)
        else:
            self.capabilities, self.period_range = PERIOD_ADJUSTABLE, (200, 65535)
        # Power-up values of the page.
        self.hold = [0, 0, 4, 0, fixed_period or 600, 500, 0, 1000]
        self.applied = list(self.hold)
        self.pending_since = None
        self.apply_count = 0
        self.requests = 0

    def advance(self):
        if self.pending_since is not None and time.monotonic() - self.pending_since >= self.settle_s:
            self.applied = list(self.hold)
            self.apply_count = (self.apply_count + 1) & 0xFFFF
            self.pending_since = None

    def inputs(self):
        self.advance()
        lit = self.applied[ENABLE] == 1
        status = (APPLYING if self.pending_since is not None else READY) | (ENABLED if lit else 0)
        regs = [0x4453, 0x0100, status, self.applied[PHASE] if lit else PHASE_OFF, self.apply_count, 300,
                self.capabilities, self.period_range[0], self.period_range[1]]
        return regs[:self.n_input]

    def valid(self, h):
        low, high = (200, 65535) if self.revision == 1 else self.period_range
        return (2 <= h[NUM_PHASES] <= 64 and h[PHASE] < h[NUM_PHASES] and h[ENABLE] <= 1
                and h[PATTERN_KIND] <= 1 and low <= h[PERIOD_CENTIPX] <= high and 1 <= h[DUTY_PERMILLE] <= 999
                and h[BLACK_PERMILLE] <= 999 and h[INTENSITY_PERMILLE] <= 1000)

    def write(self, address, values):
        """None when accepted, else the exception code."""
        if address + len(values) > N_HOLDING:
            return ModbusExceptions.IllegalAddress
        tentative = list(self.hold)
        tentative[address:address + len(values)] = values
        if not self.valid(tentative):
            return ModbusExceptions.IllegalValue
        self.advance()
        self.hold = tentative
        # One apply per accepted write; a write during the settle time restarts it.
        self.pending_since = time.monotonic()
        return None

    def answer(self, request):
        fc = request.function_code
        if fc in (3, 4):
            limit = N_HOLDING if fc == 3 else self.n_input
            if not 1 <= request.count <= 125:
                return request.doException(ModbusExceptions.IllegalValue)
            if request.address + request.count > limit:
                return request.doException(ModbusExceptions.IllegalAddress)
            regs = self.hold if fc == 3 else self.inputs()
            values = regs[request.address:request.address + request.count]
            return ReadHoldingRegistersResponse(values) if fc == 3 else ReadInputRegistersResponse(values)
        if fc == 6:
            code = self.write(request.address, [request.value])
            return request.doException(code) if code else WriteSingleRegisterResponse(request.address, request.value)
        if fc == 16:
            code = self.write(request.address, list(request.values))
            return request.doException(code) if code else WriteMultipleRegistersResponse(request.address,
                                                                                             len(request.values))
        return request.doException(ModbusExceptions.IllegalFunction)


class Trace:
    """The last serial events, each with its monotonic time."""

    def __init__(self, size=48):
        self.events = collections.deque(maxlen=size)

    def note(self, text):
        self.events.append((time.monotonic(), text))

    def dump(self, out):
        now = time.monotonic()
        print(f"pymodbus-controller: last {len(self.events)} serial events (seconds before exit):", file=out)
        for t, text in self.events:
            print(f"  -{now - t:8.3f} {text}", file=out)


class Faults:
    def __init__(self, args, trace):
        self.busy_count = args.busy_count
        self.busy_left = 0
        self.silent = False
        self.trace = trace

    def arm_busy(self):
        self.busy_left = self.busy_count
        self.trace.note("armed busy")
        print("pymodbus-controller: armed busy", flush=True)

    def toggle_silent(self):
        self.silent = not self.silent
        self.trace.note(f"silent {'on' if self.silent else 'off'}")
        print(f"pymodbus-controller: silent {'on' if self.silent else 'off'}", flush=True)

    def verdict(self):
        """What the next request gets: 'silent', 'busy' or None."""
        if self.silent:
            return "silent"
        if self.busy_left > 0:
            self.busy_left -= 1
            return "busy"
        return None


class RtuHandler(ModbusSingleRequestHandler):
    """The serial side: every request goes through the model (and the fault knobs)."""

    def data_received(self, data):
        self.server.trace.note(f"read {data.hex()}")
        super().data_received(data)

    def execute(self, request, *addr):
        ctl, faults = self.server.controller, self.server.faults
        ctl.requests += 1
        verdict = faults.verdict()
        self.server.trace.note(f"request fc {request.function_code} address {getattr(request, 'address', '-')}: "
                               f"{verdict or 'answered'}")
        if verdict == "silent":
            return
        if verdict == "busy":
            response = request.doException(ModbusExceptions.SlaveBusy)
        else:
            response = ctl.answer(request)
        response.transaction_id = request.transaction_id
        response.unit_id = request.unit_id
        self.send(response, *addr)


class LightContext:
    """Read-only view of the model for the camera's optics (Modbus TCP)."""

    def __init__(self, controller):
        self.controller = controller

    def validate(self, fc, address, count=1):
        limit = N_HOLDING if fc == 3 else self.controller.n_input if fc == 4 else 0
        return address + count <= limit

    def getValues(self, fc, address, count=1):  # pylint: disable=invalid-name
        regs = self.controller.hold if fc == 3 else self.controller.inputs()
        return regs[address:address + count]

    def setValues(self, fc, address, values):  # pylint: disable=invalid-name
        raise ValueError("the light view is read-only")


async def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("device")
    p.add_argument("--baud", type=int, default=19200)
    p.add_argument("--parity", default="E", choices="NEO")
    p.add_argument("--unit", type=int, default=1)
    p.add_argument("--settle-ms", type=float, default=3.0)
    p.add_argument("--light-port", type=int)
    p.add_argument("--busy-count", type=int, default=12)
    p.add_argument("--fixed-period-centipx", type=int, default=0)
    p.add_argument("--map-revision", type=int, default=2, choices=(1, 2))
    args = p.parse_args()
    # pymodbus logs every exception response it builds at ERROR: they are this controller's job.
    logging.getLogger("pymodbus").setLevel(logging.DEBUG if os.environ.get("PYMODBUS_DEBUG") else logging.CRITICAL)

    controller = Controller(args.settle_ms / 1000.0, args.fixed_period_centipx, args.map_revision)
    context = ModbusServerContext(slaves={args.unit: LightContext(controller)}, single=False)
    serial_server = ModbusSerialServer(context, framer=ModbusRtuFramer, port=args.device, baudrate=args.baud,
                                       parity=args.parity, bytesize=8, stopbits=1, handler=RtuHandler)
    serial_server.controller = controller
    trace = Trace()
    serial_server.trace = trace
    faults = Faults(args, trace)
    serial_server.faults = faults
    await serial_server.start()
    tasks = []
    light = ""
    if args.light_port is not None:
        light_context = ModbusServerContext(slaves=LightContext(controller), single=True)
        tcp = ModbusTcpServer(light_context, address=("127.0.0.1", args.light_port), allow_reuse_address=True)
        tasks.append(asyncio.create_task(tcp.serve_forever()))
        await tcp.serving
        port = tcp.server.sockets[0].getsockname()[1]
        light = f" light=127.0.0.1:{port}"
    print(f"pymodbus-controller: ready rtu={args.device}{light}", flush=True)

    stop = asyncio.Event()
    loop = asyncio.get_running_loop()
    for sig in (signal.SIGTERM, signal.SIGINT):
        loop.add_signal_handler(sig, stop.set)
    loop.add_signal_handler(signal.SIGUSR1, faults.arm_busy)
    loop.add_signal_handler(signal.SIGUSR2, faults.toggle_silent)
    await stop.wait()
    for sig in (signal.SIGTERM, signal.SIGINT, signal.SIGUSR1, signal.SIGUSR2):
        loop.remove_signal_handler(sig)
    for t in tasks:
        t.cancel()
    await serial_server.shutdown()
    print(f"pymodbus-controller: requests={controller.requests} applies={controller.apply_count}", file=sys.stderr)
    trace.dump(sys.stderr)


if __name__ == "__main__":
    asyncio.run(main())
    sys.exit(0)
