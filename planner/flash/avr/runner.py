"""N emulated AVR drivers on one shared line behind a pseudo-terminal, with persisted EEPROMs and LED traces.

Each driver is one simavr harness process (:func:`~planner.flash.avr.build.build_harness`)
running the reference firmware, its USART on the process's stdin/stdout. :class:`AvrBus`
is the multi-drop line: every byte the host writes to the terminal reaches every driver,
and what the drivers send goes back to the host, so the firmware's own address filter
decides who answers (docs/protocol.md section 1). Each driver's EEPROM is the 1,024-byte
file ``<eeprom dir>/<serial>.eeprom``, provisioned with its bus address, serial and
per-driver key (planner/flash/keys.py) and written through by the harness on every byte
the firmware programs; :meth:`AvrBus.power_cut` kills a driver's process (SIGKILL, at
whatever instruction it is) and boots it again from that file (:meth:`AvrBus.power_off`
leaves it off until then). At start-up each driver must answer one HELLO on its own pipe
before the host gets the line (a power-on self-test: on a loaded machine starting the
processes can take longer than the host's retries); after a power cut the host meets the
reboot as it is. With a trace folder, driver ``a``'s LED pin is traced to
``<trace dir>/<a>.vcd`` (restarted at every boot).
``peers`` share the line with the firmware: callables that take the host's bytes and return
the bytes they send back (a :class:`~planner.flash.sim.driver.SimulatedDriver`'s
``receive``), such as the hostile drivers of tests/flash/test_hostile_avr.py.
"""

from __future__ import annotations

import os
import select
import struct
import subprocess
import threading
import time
import tty
import zlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from planner.errors import UsageError
from planner.flash.avr.build import EEPROM_BYTES, build_firmware, build_harness
from planner.flash.keys import driver_key
from planner.flash.wire import Command, Deframer, Packet, WireError, decode, encode

PROVISION_MAGIC = b"VLPK"
PROVISION = struct.Struct("<4sHH16s32s")  # magic, bus address, 0, serial (NUL-padded), driver key; then CRC-32
MAX_DRIVERS = 64
"""Most emulated drivers one bus runs (each is a process pacing an MCU in real time)."""


def provision_block(address: int, serial: str, key: bytes) -> bytes:
    """The EEPROM's first 60 bytes for a driver (firmware_templates/driver/driver.h has the map)."""
    body = PROVISION.pack(PROVISION_MAGIC, address, 0, serial.encode("ascii"), key)
    return body + struct.pack("<I", zlib.crc32(body))


def provision(path: Path, address: int, serial: str, key: bytes) -> None:
    """Make ``path`` a provisioned EEPROM (erased if new; an existing one keeps its slots), mode 0600: it holds
    the driver's key."""
    try:
        if not path.exists():  # it holds the driver's key: readable by its owner only
            fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
            with os.fdopen(fd, "wb") as f:
                f.write(b"\xff" * EEPROM_BYTES)
        os.chmod(path, 0o600)
        if path.stat().st_size != EEPROM_BYTES:
            raise UsageError(f"{path}: {path.stat().st_size} bytes, not a {EEPROM_BYTES}-byte EEPROM image; "
                             "move it away or use another `eeprom_dir`")
        with open(path, "r+b") as f:
            f.write(provision_block(address, serial, key))
        path.chmod(0o600)  # it holds the driver's key
    except OSError as exc:
        raise UsageError(f"{path}: cannot use as an EEPROM image ({exc.strerror or exc})") from None


def _decoded(frame: bytes) -> Packet | None:
    try:
        return decode(frame)
    except WireError:
        return None


@dataclass
class EmulatedDriver:
    address: int
    serial: str
    eeprom_path: Path
    trace_path: Path | None
    process: subprocess.Popen | None = None
    boots: int = 0


class AvrBus:
    """``n_drivers`` emulated drivers at addresses ``first_address``.. with serials ``<prefix><address:06d>``."""

    def __init__(self, n_drivers: int, site_key: bytes, eeprom_dir: Path, *, first_address: int = 1,
                 serial_prefix: str = "AVR-", trace_dir: Path | None = None, build_dir: Path | None = None,
                 peers: Sequence[Callable[[bytes], bytes]] = ()):
        last = first_address + n_drivers - 1
        if not 1 <= n_drivers <= MAX_DRIVERS or not 1 <= first_address <= last <= 0xFFFE:
            raise UsageError(f"{n_drivers} emulated drivers from address {first_address}: run 1 to {MAX_DRIVERS} "
                             "at addresses in 1..65534")
        if len(serial_prefix) + 6 > 16 or not serial_prefix.isascii():
            raise UsageError(f"serial prefix {serial_prefix!r}: at most 10 ASCII characters (serials have 16)")
        if not 16 <= len(site_key) <= 64:
            raise UsageError(f"site key of {len(site_key)} bytes; the protocol needs 16 to 64")
        for folder in (eeprom_dir, trace_dir):
            if folder is not None:
                try:
                    folder.mkdir(parents=True, exist_ok=True)
                except OSError as exc:
                    raise UsageError(f"{folder}: cannot make the folder ({exc.strerror or exc})") from None
        self.firmware, self.harness = build_firmware(build_dir), build_harness(build_dir)
        self.drivers: list[EmulatedDriver] = []
        for address in range(first_address, last + 1):
            serial = f"{serial_prefix}{address:06d}"
            path = eeprom_dir / f"{serial}.eeprom"
            provision(path, address, serial, driver_key(site_key, serial))
            self.drivers.append(EmulatedDriver(address, serial, path,
                                               trace_dir / f"{address}.vcd" if trace_dir is not None else None))
        self.peers = list(peers)  # each peer's ``receive``: it hears every byte the host sends
        self.last_request: tuple[int, int] | None = None  # (address, command) the host last sent, whole
        self._host_frames = Deframer()
        self._lock = threading.Lock()
        self._wake_r, self._wake_w = os.pipe()
        self._stopping = self._closed = False
        self._thread: threading.Thread | None = None
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)  # no echo, no line editing: bytes pass unchanged
        os.set_blocking(self.master, False)
        self.port = os.ttyname(self.slave)
        try:
            for driver in self.drivers:
                self._boot(driver)
            for driver in self.drivers:
                self._await_boot(driver)
        except BaseException:
            self.close()  # no MCU left running, no terminal left open
            raise

    def driver(self, address: int) -> EmulatedDriver:
        for d in self.drivers:
            if d.address == address:
                return d
        raise UsageError(f"no emulated driver at address {address}")

    def _boot(self, driver: EmulatedDriver) -> None:
        trace = str(driver.trace_path) if driver.trace_path is not None else "-"
        driver.process = subprocess.Popen([str(self.harness), str(self.firmware), str(driver.eeprom_path), trace],
                                          stdin=subprocess.PIPE, stdout=subprocess.PIPE, bufsize=0)
        driver.boots += 1

    def _await_boot(self, driver: EmulatedDriver, timeout_s: float = 30.0) -> None:
        """Power-on self-test, before the host gets the line: the driver answers a HELLO on its own pipe."""
        p = driver.process
        assert p is not None and p.stdin is not None and p.stdout is not None
        deframer, deadline = Deframer(), time.monotonic() + timeout_s
        probes = answers = 0
        next_probe = time.monotonic()
        while time.monotonic() < deadline:
            if not answers and time.monotonic() >= next_probe:  # again every 0.5 s until one is answered
                p.stdin.write(encode(Packet(driver.address, 0, 0, Command.HELLO)))
                probes, next_probe = probes + 1, time.monotonic() + 0.5
            ready, _, _ = select.select([p.stdout], [], [], 0.05)
            data = os.read(p.stdout.fileno(), 4096) if ready else b""
            if ready and not data:
                break  # the harness exited
            answers += sum(_decoded(f) is not None for f in deframer.feed(data))
            if answers >= probes > 0:  # every probe answered (repeats from the seq cache): the line is clean
                return
        raise UsageError(f"emulated driver {driver.serial} (address {driver.address}) did not answer at power-up "
                         f"within {timeout_s:g} s; run {self.harness} {self.firmware} {driver.eeprom_path} - by hand "
                         "to see why")

    def power_cut(self, address: int) -> None:
        """Cut the driver's power at this instant (SIGKILL) and power it up again from its EEPROM."""
        driver = self.driver(address)
        with self._lock:
            self._halt(driver, kill=True)
            self._boot(driver)
        os.write(self._wake_w, b"x")

    def power_off(self, address: int) -> None:
        """Cut the driver's power and leave it off (a driver taken from the line); :meth:`power_cut` boots it."""
        driver = self.driver(address)
        with self._lock:
            self._halt(driver, kill=True)
        os.write(self._wake_w, b"x")

    @staticmethod
    def _halt(driver: EmulatedDriver, kill: bool) -> None:
        p = driver.process
        if p is None:
            return
        if kill:
            p.kill()
        else:
            p.terminate()
        try:
            p.wait(timeout=5)
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait()
        for pipe in (p.stdin, p.stdout):
            if pipe is not None:
                pipe.close()
        driver.process = None

    def serve(self, stop_fd: int | None = None) -> None:
        """Move bytes between the terminal and the drivers until :meth:`stop` (or ``stop_fd`` is readable)."""
        while True:
            with self._lock:
                outs = {d.process.stdout.fileno(): (d, d.process) for d in self.drivers
                        if d.process is not None and d.process.stdout is not None and not d.process.stdout.closed}
            watch = [self.master, self._wake_r, *outs] + ([stop_fd] if stop_fd is not None else [])
            try:
                readable, _, _ = select.select(watch, [], [])
            except (OSError, ValueError):  # a pipe closed by a power cut meanwhile: look again
                continue
            if stop_fd is not None and stop_fd in readable:
                return
            if self._wake_r in readable:
                os.read(self._wake_r, 512)
                if self._stopping:
                    return
                continue  # a driver was restarted: watch its new pipe
            if self.master in readable:
                self._to_drivers()
            for fd in readable:
                if fd in outs:
                    self._from_driver(fd, *outs[fd])

    def _to_drivers(self) -> None:
        try:
            data = os.read(self.master, 4096)
        except OSError:  # nobody has the terminal open
            time.sleep(0.05)
            return
        for frame in self._host_frames.feed(data):  # only to tell tests whom the host is talking to
            packet = _decoded(frame)
            if packet is not None:
                self.last_request = (packet.address, packet.command)
        with self._lock:
            for d in self.drivers:
                if d.process is not None and d.process.stdin is not None:
                    try:
                        d.process.stdin.write(data)
                    except (OSError, ValueError):  # the driver is off: the bytes are lost, as on a real line
                        pass
        for receive in self.peers:
            answer = receive(data)
            if answer:
                try:
                    os.write(self.master, answer)
                except OSError:  # as _from_driver: lost, as on an unread line
                    pass

    def _from_driver(self, fd: int, driver: EmulatedDriver, process: subprocess.Popen) -> None:
        with self._lock:
            if driver.process is not process:  # power-cut since select: the fd may be the new process's
                return
            try:
                data = os.read(fd, 4096)
            except OSError:
                return
            if not data:  # the process ended on its own
                self._halt(driver, kill=True)
                return
        try:
            os.write(self.master, data)
        except OSError:  # the terminal's buffer is full or closed: lost, as on an unread line
            pass

    def start(self) -> AvrBus:
        """Serve in a background thread (tests); :meth:`close` stops it."""
        self._thread = threading.Thread(target=self.serve, name="avr-bus", daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stopping = True
        os.write(self._wake_w, b"x")
        if self._thread is not None:
            self._thread.join(timeout=5)
            self._thread = None

    def close(self) -> None:
        """Stop serving, stop every driver (SIGTERM: traces flushed) and close the terminal (once)."""
        if self._closed:
            return
        self._closed = True
        self.stop()
        with self._lock:
            for d in self.drivers:
                self._halt(d, kill=False)
        for fd in (self.master, self.slave, self._wake_r, self._wake_w):
            try:
                os.close(fd)
            except OSError:
                pass

    def __enter__(self) -> AvrBus:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
