"""Build the reference driver firmware (avr-gcc) and its simavr harness (host gcc), cached by source hash.

Sources: ``firmware_templates/driver/*.c``/``*.h`` (the firmware, installed as
``planner.firmware_templates``) and ``harness.c`` beside this module. Each build lands in
``<build dir>/<kind>-<hash of sources and flags>/`` and is reused while the sources are
unchanged; the default build dir is ``$XDG_CACHE_HOME/vlp-plan/avr`` (``~/.cache/...``).
A missing tool is one :class:`ToolchainError` line naming the Debian packages to install.
"""

from __future__ import annotations

import hashlib
import os
import re
import shutil
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path

from planner.defaults import MCU_CLOCK_HZ as DEFAULT_MCU_CLOCK_HZ
from planner.errors import UsageError
from planner.firmware.render import default_template_dir

MCU = "atmega328p"
MCU_CLOCK_HZ = int(DEFAULT_MCU_CLOCK_HZ)  # the reference driver's ATmega328P
FLASH_BYTES, RAM_BYTES, EEPROM_BYTES = 32 * 1024, 2 * 1024, 1024
FIRMWARE_SOURCES = ("main.c", "protocol.c", "codec.c", "sha256.c")
FIRMWARE_HEADERS = ("driver.h", "codec.h", "sha256.h")
HOST_TEST_SOURCES = ("host_test.c", "codec.c", "sha256.c")
AVR_FLAGS = ("-mmcu=" + MCU, f"-DF_CPU={MCU_CLOCK_HZ}UL", "-std=gnu99", "-Os", "-Wall", "-Wextra", "-Werror",
             "-ffunction-sections", "-fdata-sections", "-Wl,--gc-sections")
HOST_FLAGS = ("-std=c99", "-pedantic", "-O2", "-Wall", "-Wextra", "-Werror")
SIMAVR_INCLUDE = Path("/usr/include/simavr")
APT_PACKAGES = "gcc-avr avr-libc simavr libsimavr-dev libsimavrparts1"


class ToolchainError(UsageError):
    """A compiler, header or library the emulated drivers need is missing, or a build failed."""


@dataclass(frozen=True)
class MemoryUse:
    """What the firmware takes of the chip [bytes] (avr-size: flash = text + data, RAM = data + bss)."""

    flash_bytes: int
    ram_bytes: int

    def check(self) -> None:
        if self.flash_bytes > FLASH_BYTES or self.ram_bytes > RAM_BYTES:
            raise ToolchainError(f"the firmware needs {self.flash_bytes} bytes of flash and {self.ram_bytes} of "
                                 f"static RAM; the {MCU} has {FLASH_BYTES} and {RAM_BYTES}")


def firmware_dir() -> Path:
    """The firmware's C sources (installed with the package)."""
    return default_template_dir() / "driver"


def harness_source() -> Path:
    return Path(__file__).with_name("harness.c")


def default_build_dir() -> Path:
    cache = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(cache) / "vlp-plan" / "avr"


def _tool(name: str) -> str:
    path = shutil.which(name)
    if path is None:
        raise ToolchainError(f"{name} not found: the emulated AVR drivers need it; install the Debian packages "
                             f"with: apt-get install {APT_PACKAGES}")
    return path


def _cached(kind: str, sources: list[Path], flags: tuple[str, ...], build_dir: Path | None,
            compile_into: _Compile) -> Path:
    digest = hashlib.sha256("\0".join(flags).encode())
    for path in sources:
        try:
            digest.update(path.name.encode() + b"\0" + path.read_bytes())
        except OSError as exc:
            raise ToolchainError(f"{path}: cannot read the source ({exc.strerror or exc}); reinstall vlp-plan") from None
    folder = (build_dir or default_build_dir()) / f"{kind}-{digest.hexdigest()[:16]}"
    target = folder / kind
    if target.is_file():
        return target
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ToolchainError(f"{folder}: cannot make the build folder ({exc.strerror or exc})") from None
    with tempfile.TemporaryDirectory(dir=folder) as scratch:
        out = Path(scratch) / kind
        compile_into(out)
        os.replace(out, target)  # atomic: a parallel build of the same sources writes the same file
    return target


class _Compile:
    def __init__(self, command: list[str], what: str):
        self.command, self.what = command, what

    def __call__(self, out: Path) -> None:
        proc = subprocess.run([*self.command, "-o", str(out)], capture_output=True, text=True)
        if proc.returncode != 0:
            first = next((line for line in proc.stderr.splitlines() if "error" in line), proc.stderr.strip()[:300])
            hint = f"; install the headers and libraries with: apt-get install {APT_PACKAGES}" \
                if "No such file" in first or "cannot find -l" in first else ""
            raise ToolchainError(f"building the {self.what} failed: {first}{hint}")


def build_firmware(build_dir: Path | None = None) -> Path:
    """The firmware ELF for the ATmega328P (``-Wall -Wextra -Werror``), built if not cached."""
    gcc = _tool("avr-gcc")
    src = firmware_dir()
    sources = [src / name for name in FIRMWARE_SOURCES]
    return _cached("driver.elf", sources + [src / name for name in FIRMWARE_HEADERS], AVR_FLAGS, build_dir,
                   _Compile([gcc, *AVR_FLAGS, *map(str, sources)], "driver firmware"))


def build_harness(build_dir: Path | None = None) -> Path:
    """The simavr harness executable (host gcc against libsimavr), built if not cached."""
    gcc = _tool("gcc")
    if not (SIMAVR_INCLUDE / "sim_avr.h").is_file():
        raise ToolchainError(f"simavr's headers ({SIMAVR_INCLUDE}) are missing; install them with: "
                             f"apt-get install {APT_PACKAGES}")
    flags = ("-O2", "-Wall", "-Wextra", "-Werror", f"-I{SIMAVR_INCLUDE}")
    libs = ["-lsimavr", "-l:libelf.so.1"]
    return _cached("vlp-avr-harness", [harness_source()], flags + tuple(libs), build_dir,
                   _Compile([gcc, *flags, str(harness_source()), *libs], "simavr harness"))


def build_host_test(build_dir: Path | None = None) -> Path:
    """The firmware's codec and hash code compiled for this machine (tests compare it with Python's)."""
    gcc = _tool("gcc")
    src = firmware_dir()
    sources = [src / name for name in HOST_TEST_SOURCES]
    return _cached("host-test", sources + [src / "codec.h", src / "sha256.h"], HOST_FLAGS, build_dir,
                   _Compile([gcc, *HOST_FLAGS, *map(str, sources)], "host test of the firmware's C"))


def memory_use(elf: Path) -> MemoryUse:
    """Flash and static RAM the firmware takes, from ``avr-size``."""
    proc = subprocess.run([_tool("avr-size"), "-A", str(elf)], capture_output=True, text=True, check=True)
    sizes = {m[1]: int(m[2]) for m in re.finditer(r"^(\.\w+)\s+(\d+)", proc.stdout, re.M)}
    text, data, bss = sizes.get(".text", 0), sizes.get(".data", 0), sizes.get(".bss", 0)
    return MemoryUse(text + data, data + bss)
