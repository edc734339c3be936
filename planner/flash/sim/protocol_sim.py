"""pyserial URL handler ``sim://``: simulated drivers in process, no hardware.

Call :func:`register` once, then ``serial.serial_for_url(url, timeout=...)`` with::

    sim://?drivers=4&key=<hex>&faults=corrupt=0.001,seed=3&flash=<dir>

URL query parameters:

- ``drivers``: how many drivers share the line (default 1);
- ``first``: the first bus address (default 1); drivers are at ``first .. first + drivers - 1``;
- ``key``: the site key, hex (16 to 64 bytes; required); each driver keeps only the key derived
  from it and its serial (:func:`planner.flash.keys.driver_key`);
- ``prefix``: serial number prefix (default ``SIM-``; serials are ``SIM-000001`` for address 1);
- ``flash``: folder of flash files ``<serial>.flash``, kept between opens (default: RAM,
  lost on close);
- ``paced``: ``1`` to make bytes take their line time at the port's baud rate, both ways, and
  WRITE/COMMIT the driver's programming time (for benchmarks; default 0, instant);
- ``faults``: a fault spec (:meth:`planner.flash.sim.bus.Faults.parse`), e.g.
  ``corrupt=0.001,drop=0.0001,reset=0.01,power=0.01,stall=0.01,stall_s=0.5,seed=3``;
- ``slot_size`` [bytes] (default 4096), ``max_block`` [bytes] (default 256) and
  ``block_write_us`` [us] (default 2000): what every driver's HELLO reports;
- ``protocol``: 2 (default, HELLO answers the host's challenge) or 1 (unauthenticated, as old drivers).

Unpaced, drivers answer at once (no line time); a stalled answer becomes readable ``stall_s``
later. :meth:`Serial.read` blocks up to ``timeout`` like a real port. One thread per port.
"""

from __future__ import annotations

import time
import urllib.parse

import serial
from serial import SerialBase, SerialException
from serial.serialutil import PortNotOpenError, to_bytes  # type: ignore[attr-defined]  # to_bytes: not in types-pyserial

from planner.flash.keys import site_key_from
from planner.flash.sim.bus import Faults, SimBus, SimConfigError, make_bus
from planner.flash.wire import Command, WireError, decode

PACKAGE = "planner.flash.sim"
_INTS = {"drivers": 1, "first": 1, "slot_size": 4096, "max_block": 256, "block_write_us": 2000, "protocol": 2}
_PARAMS = (*_INTS, "key", "prefix", "flash", "faults", "paced")


class SimUrlError(SimConfigError, SerialException):
    """A ``sim://`` URL that cannot be opened (a PlannerError and a pyserial SerialException)."""


def register() -> None:
    """Let ``serial.serial_for_url`` open ``sim://`` URLs (idempotent)."""
    if PACKAGE not in serial.protocol_handler_packages:
        serial.protocol_handler_packages.append(PACKAGE)


def bus_from_url(url: str) -> SimBus:
    """The simulated line a ``sim://`` URL describes."""
    parts = urllib.parse.urlsplit(url)
    if parts.scheme.lower() != "sim":
        raise SimUrlError(f"{parts.scheme or '(none)'}:// is not a sim:// URL")
    query = urllib.parse.parse_qs(parts.query, keep_blank_values=True)
    unknown = sorted(set(query) - set(_PARAMS))
    if unknown:
        raise SimUrlError(f"sim:// URL: unknown parameter(s) {', '.join(unknown)}; known: {', '.join(_PARAMS)}")
    one = {name: values[-1] for name, values in query.items()}
    ints = {}
    for name, default in _INTS.items():
        try:
            ints[name] = int(one.get(name, default))
        except ValueError:
            raise SimUrlError(f"sim:// URL: {name}={one[name]!r} is not a whole number") from None
    try:
        key = site_key_from(one.get("key", "").encode("utf-8", "surrogateescape"), raw=False)
    except ValueError as exc:
        raise SimUrlError(f"sim:// URL: key: {exc}") from None
    try:
        return make_bus(ints["drivers"], key, first_address=ints["first"], serial_prefix=one.get("prefix", "SIM-"),
                        flash_dir=one.get("flash") or None, slot_size=ints["slot_size"],
                        max_block=ints["max_block"], block_write_us=ints["block_write_us"], protocol=ints["protocol"],
                        faults=Faults.parse(one.get("faults", "")))
    except SimConfigError as exc:
        raise SimUrlError(f"sim:// URL: {exc}") from None


class Serial(SerialBase):
    """A serial port whose other end is a :class:`~planner.flash.sim.bus.SimBus`."""

    def __init__(self, *args, **kwargs):
        self.bus: SimBus | None = None
        self._rx = bytearray()
        self._later: list[tuple[float, bytes]] = []  # (time readable [s, monotonic], bytes)
        super().__init__(*args, **kwargs)

    def open(self) -> None:
        if self.is_open:
            raise SerialException("port is already open")
        if self.port is None:
            raise SerialException("port must be configured before it can be used")
        self.bus = bus_from_url(self.port)
        query = urllib.parse.parse_qs(urllib.parse.urlsplit(self.port).query)
        self._paced = query.get("paced", ["0"])[-1] == "1"
        self._line_free = 0.0
        self._rx.clear()
        self._later.clear()
        self.is_open = True

    def close(self) -> None:
        if self.bus is not None:
            self.bus.close()
            self.bus = None
        self.is_open = False

    def _reconfigure_port(self, *args, **kwargs) -> None:
        """Baud rate, timeouts and framing need no action: the simulated line is ideal."""

    def _update_rts_state(self) -> None:
        pass

    def _update_dtr_state(self) -> None:
        pass

    def _update_break_state(self) -> None:
        pass

    @property
    def cts(self) -> bool:
        return True

    @property
    def dsr(self) -> bool:
        return True

    @property
    def ri(self) -> bool:
        return False

    @property
    def cd(self) -> bool:
        return True

    def _arrive(self) -> float | None:
        """Move answers whose time has come into the input buffer; the next arrival time, if any."""
        now = time.monotonic()
        due = [item for item in self._later if item[0] <= now]
        self._later = [item for item in self._later if item[0] > now]
        for _, data in due:
            self._rx += data
        return min((t for t, _ in self._later), default=None)

    @property
    def in_waiting(self) -> int:
        if not self.is_open:
            raise PortNotOpenError()
        self._arrive()
        return len(self._rx)

    def read(self, size: int = 1) -> bytes:
        """Up to ``size`` bytes, waiting at most ``timeout`` [s] (None: until a pending answer arrives)."""
        if not self.is_open:
            raise PortNotOpenError()
        deadline = None if self.timeout is None else time.monotonic() + self.timeout
        while True:
            upcoming = self._arrive()
            if len(self._rx) >= size:
                break
            now = time.monotonic()
            waits = [t - now for t in (deadline, upcoming) if t is not None]
            if not waits or (deadline is not None and now >= deadline):
                break  # nothing more can arrive (no thread writes), or the timeout passed
            time.sleep(max(0.0, min(waits)))
        data = bytes(self._rx[:size])
        del self._rx[:size]
        return data

    def write(self, data) -> int:
        if not self.is_open or self.bus is None:
            raise PortNotOpenError()
        data = to_bytes(data)
        now = time.monotonic()
        if self._paced:  # the bytes take 10 bit times each on the line, both ways; the driver programs
            now = self._line_free = max(now, self._line_free) + len(data) * 10 / self.baudrate
        for delay_s, answer in self.bus.send(data):
            if self._paced:
                delay_s += self._driver_time_s(answer) + len(answer) * 10 / self.baudrate
            if delay_s > 0:
                self._later.append((now + delay_s, answer))
            else:
                self._rx += answer
        return len(data)

    def _driver_time_s(self, answer: bytes) -> float:
        """Programming time the answered request cost: a block for WRITE, two for COMMIT."""
        try:
            packet = decode(answer.rstrip(b"\x00"))
        except WireError:
            return 0.0
        per_command: dict[int, int] = {Command.WRITE: 1, Command.COMMIT: 2}
        blocks = per_command.get(packet.command, 0)
        assert self.bus is not None  # write() checked it
        driver = next((d for d in self.bus.drivers if d.address == packet.address), None)
        return blocks * (driver.block_write_us if driver else 0) * 1e-6

    def reset_input_buffer(self) -> None:
        """Discard what has arrived; answers still on their way (stalled) arrive later."""
        if not self.is_open:
            raise PortNotOpenError()
        self._arrive()
        self._rx.clear()

    def reset_output_buffer(self) -> None:
        if not self.is_open:
            raise PortNotOpenError()

    @property
    def out_waiting(self) -> int:
        return 0
