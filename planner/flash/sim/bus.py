"""Simulated drivers sharing one line (multi-drop), with seeded line and driver faults.

The host's bytes reach every driver; their answers are concatenated. A
:class:`Faults` spec adds, from one seeded ``random.Random`` (so a run repeats
exactly): bit flips and dropped bytes in either direction, and per request resets,
power cuts and stalls of the addressed driver.
"""

from __future__ import annotations

import random
from dataclasses import dataclass, fields
from pathlib import Path

from planner.errors import UsageError
from planner.flash.sim.driver import SimulatedDriver
from planner.flash.sim.memory import Flash
from planner.flash.wire import ANY_ADDRESS, MAX_FRAME, WireError, decode

_KEYS = {"corrupt": "corrupt_per_byte", "drop": "drop_per_byte", "reset": "reset_per_request",
         "power": "power_cut_per_request", "stall": "stall_per_request", "stall_s": "stall_s", "seed": "seed"}


class SimConfigError(UsageError):
    """A simulator setting (fault spec, URL parameter, flag) is wrong."""


@dataclass(frozen=True)
class Faults:
    """Fault rates: per byte on the line, per request for the addressed driver.

    A reset loses the driver's RAM, before the request or after it (then its answer is
    lost too); a power cut stops the next flash programming after a random number of
    bytes (0 .. 2 x max block) and the driver reboots; a stalled answer appears
    ``stall_s`` [s] late (later answers are not held back, so a retry is answered
    from the seq cache while the late answer is still on its way).
    """

    corrupt_per_byte: float = 0.0
    drop_per_byte: float = 0.0
    reset_per_request: float = 0.0
    power_cut_per_request: float = 0.0
    stall_per_request: float = 0.0
    stall_s: float = 0.5
    seed: int = 0

    @classmethod
    def parse(cls, spec: str) -> Faults:
        """From ``"corrupt=0.001,drop=0,reset=0.01,power=0.01,stall=0.01,stall_s=0.5,seed=3"`` (any subset)."""
        values: dict = {}
        for item in filter(None, (part.strip() for part in spec.split(","))):
            key, sep, text = item.partition("=")
            name = _KEYS.get(key.strip(), key.strip() if key.strip() in _KEYS.values() else None)
            if not sep or name is None:
                raise SimConfigError(f"fault spec item {item!r}: expected NAME=VALUE with NAME one of "
                                     f"{', '.join(_KEYS)}")
            try:
                values[name] = int(text) if name == "seed" else float(text)
            except ValueError:
                raise SimConfigError(f"fault spec item {item!r}: {text!r} is not a number") from None
        faults = cls(**values)
        for f in fields(cls):
            value = getattr(faults, f.name)
            if f.name.endswith(("_byte", "_request")) and not 0 <= value <= 1:
                raise SimConfigError(f"fault rate {f.name}={value} must be a probability in [0, 1]")
        if not 0 <= faults.stall_s < 3600:
            raise SimConfigError(f"stall_s={faults.stall_s} must be in [0, 3600) seconds")
        return faults


class SimBus:
    """``drivers`` on one line; :meth:`send` delivers host bytes and returns timed answers."""

    def __init__(self, drivers: list[SimulatedDriver], faults: Faults | None = None):
        self.drivers = drivers
        self.faults = faults or Faults()
        self.rng = random.Random(self.faults.seed)
        self.events = {"corrupted": 0, "dropped": 0, "resets": 0, "power_cuts": 0, "stalls": 0}
        self._pending = bytearray()
        self._stall_once: dict[int, float] = {}

    def stall(self, address: int, seconds: float) -> None:
        """Delay the next answer of the driver at ``address`` by ``seconds`` [s] (a one-shot hook)."""
        self._stall_once[address] = seconds

    def send(self, data: bytes) -> list[tuple[float, bytes]]:
        """Host bytes onto the line; the answers as (delay [s], bytes), in the order sent."""
        self._pending += data
        replies: list[tuple[float, bytes]] = []
        while True:
            end = self._pending.find(0)
            if end < 0 and len(self._pending) <= 2 * MAX_FRAME:
                return replies
            end = end + 1 if end >= 0 else len(self._pending)
            chunk = bytes(self._pending[:end])
            del self._pending[:end]
            replies += self._deliver(chunk)

    def _deliver(self, chunk: bytes) -> list[tuple[float, bytes]]:
        f, rng = self.faults, self.rng
        target = self._target(chunk)
        reset_before = reset_after = False
        delay_s = 0.0
        if target is not None:
            if f.reset_per_request and rng.random() < f.reset_per_request:
                reset_before, reset_after = (True, False) if rng.random() < 0.5 else (False, True)
                self.events["resets"] += 1
            if f.power_cut_per_request and rng.random() < f.power_cut_per_request:
                target.power_cut_after(rng.randrange(2 * target.max_block))
                self.events["power_cuts"] += 1
            if f.stall_per_request and rng.random() < f.stall_per_request:
                delay_s = f.stall_s
                self.events["stalls"] += 1
            delay_s = self._stall_once.pop(target.address, delay_s)
        if reset_before:
            target.reset()  # type: ignore[union-attr]
        line = self._damage(chunk)
        replies = []
        for driver in self.drivers:
            out = driver.receive(line)
            if driver is target and reset_after:
                driver.reset()
                continue
            if out:
                replies.append((delay_s if driver is target else 0.0, self._damage(out)))
        return replies

    def _target(self, chunk: bytes) -> SimulatedDriver | None:
        """The driver a well-formed request addresses (the first one for "any driver")."""
        try:
            packet = decode(chunk.rstrip(b"\x00"))
        except WireError:
            return None
        if packet.is_response:
            return None
        for driver in self.drivers:
            if packet.address in (driver.address, ANY_ADDRESS):
                return driver
        return None

    def _damage(self, data: bytes) -> bytes:
        """``data`` after the line: random bit flips and lost bytes."""
        f, rng = self.faults, self.rng
        if not (f.corrupt_per_byte or f.drop_per_byte):
            return data
        out = bytearray()
        for byte in data:
            if f.drop_per_byte and rng.random() < f.drop_per_byte:
                self.events["dropped"] += 1
                continue
            if f.corrupt_per_byte and rng.random() < f.corrupt_per_byte:
                byte ^= 1 << rng.randrange(8)
                self.events["corrupted"] += 1
            out.append(byte)
        return bytes(out)

    def close(self) -> None:
        for driver in self.drivers:
            driver.flash.close()


MAX_SLOT_BYTES = 1 << 20
"""Largest simulated slot [bytes]: a driver's configuration image is a few hundred bytes."""

MAX_SIM_FLASH_BYTES = 1 << 30
"""Most flash the simulated drivers of one bus hold together [bytes] (RAM or files)."""


def make_bus(n_drivers: int, site_key: bytes, *, first_address: int = 1, serial_prefix: str = "SIM-",
             flash_dir: Path | str | None = None, slot_size: int = 4096, max_block: int = 256,
             block_write_us: int = 2000, faults: Faults | None = None, protocol: int = 2) -> SimBus:
    """``n_drivers`` at addresses ``first_address``.. with serials ``<prefix><address:06d>``.

    With ``flash_dir`` each driver's flash is the file ``<serial>.flash`` there (kept
    between runs); otherwise it lives in RAM.
    """
    last = first_address + n_drivers - 1
    if n_drivers < 1 or not 1 <= first_address <= last <= 0xFFFE:
        raise SimConfigError(f"{n_drivers} drivers from address {first_address}: addresses must lie in 1..65534 "
                             "and there must be at least one driver")
    if not 16 <= slot_size <= MAX_SLOT_BYTES or not 1 <= max_block <= 0xFFFF:
        raise SimConfigError(f"slot_size={slot_size}, max_block={max_block}: slots hold 16 to {MAX_SLOT_BYTES:,} "
                             "bytes and a block 1 to 65535")
    if not 0 <= block_write_us <= 10_000_000:
        raise SimConfigError(f"block_write_us={block_write_us}: a block's programming time is 0 to 10 s")
    if 2 * slot_size * n_drivers > MAX_SIM_FLASH_BYTES:
        raise SimConfigError(f"{n_drivers} drivers with two {slot_size:,}-byte slots need "
                             f"{2 * slot_size * n_drivers / 2**20:,.0f} MiB of flash, more than the simulator's "
                             f"{MAX_SIM_FLASH_BYTES / 2**20:,.0f} MiB; use fewer drivers or a smaller slot_size")
    if len(serial_prefix) + 6 > 16 or not serial_prefix.isascii():
        raise SimConfigError(f"serial prefix {serial_prefix!r}: at most 10 ASCII characters (serials have 16)")
    folder = Path(flash_dir) if flash_dir is not None else None
    if folder is not None:
        try:
            folder.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise SimConfigError(f"{folder}: cannot make the flash folder ({exc.strerror or exc})") from None
    drivers: list[SimulatedDriver] = []
    flash: Flash | None = None
    try:
        for address in range(first_address, last + 1):
            serial = f"{serial_prefix}{address:06d}"
            flash = Flash(slot_size, folder / f"{serial}.flash" if folder is not None else None)
            drivers.append(SimulatedDriver(address, serial, site_key, flash, max_block=max_block,
                                           block_write_us=block_write_us, protocol=protocol))
            flash = None
    except UsageError as exc:
        for f in [d.flash for d in drivers] + ([flash] if flash else []):
            f.close()
        raise SimConfigError(str(exc)) from None
    return SimBus(drivers, faults)
