"""The reference driver firmware's build (avr-gcc, warnings as errors, fits the chip) and its C compiled for
this machine against Python: SHA-256, HMAC, CRC-32, COBS. Its life on simavr: test_driver_avr.py.
Needs the Debian packages gcc-avr avr-libc (.ci/run installs them).
"""

import hashlib
import hmac
import random
import subprocess
import zlib
from pathlib import Path

import pytest
from cobs import cobs

from planner.flash.avr.build import (
    AVR_FLAGS,
    FLASH_BYTES,
    RAM_BYTES,
    build_firmware,
    build_harness,
    build_host_test,
    memory_use,
)

pytestmark = pytest.mark.needs_avr


# The firmware's C, compiled for this machine, against Python.
@pytest.fixture(scope="module")
def host_test() -> Path:
    return build_host_test()


def _run(binary: Path, *args: str) -> str:
    return subprocess.run([str(binary), *args], capture_output=True, text=True, check=True).stdout.strip()


def test_sha256_and_hmac_match_hashlib(host_test):
    rng = random.Random(1)
    for n in [0, 1, 3, 55, 56, 63, 64, 65, 119, 120, 127, 128, 132, 168, 200, 1000]:
        data = rng.randbytes(n)
        assert _run(host_test, "sha", data.hex()) == hashlib.sha256(data).hexdigest(), n
        for key_bytes in (1, 16, 32, 64):
            key = rng.randbytes(key_bytes)
            assert _run(host_test, "hmac", key.hex(), data.hex()) == hmac.new(key, data, hashlib.sha256).hexdigest()


def test_crc32_and_cobs_match_python(host_test):
    rng = random.Random(2)
    for n in [1, 2, 11, 100, 253, 254, 255, 600]:
        data = rng.randbytes(n)
        assert int(_run(host_test, "crc", data.hex()), 16) == zlib.crc32(data)
        assert _run(host_test, "cobs", cobs.encode(data).hex()) == data.hex()
        damaged = bytearray(cobs.encode(data))
        damaged[rng.randrange(len(damaged))] = rng.randrange(1, 256)
        try:
            expected = cobs.decode(bytes(damaged)).hex()
        except cobs.DecodeError:
            expected = "error"
        assert _run(host_test, "cobs", damaged.hex()) == expected
    assert _run(host_test, "cobs", "0200") == "error"  # a zero inside a frame


# Item 1: the firmware builds with warnings as errors and fits the chip.
def test_firmware_builds_with_werror_and_fits(tmp_path):
    elf = build_firmware(tmp_path)  # a fresh build, not the cache
    use = memory_use(elf)
    assert 0 < use.flash_bytes <= FLASH_BYTES // 2 and 0 < use.ram_bytes <= RAM_BYTES // 2, use
    bad = tmp_path / "warn.c"
    bad.write_text("int main(void) { int unused; return 0; }\n")
    proc = subprocess.run(["avr-gcc", *AVR_FLAGS, str(bad), "-o", str(tmp_path / "warn.elf")], capture_output=True,
                          text=True)
    assert proc.returncode != 0 and "unused" in proc.stderr  # a warning stops the build
    assert build_harness().is_file()


def test_a_missing_toolchain_is_one_line_naming_the_packages(tmp_path, monkeypatch):
    import planner.flash.avr.build as build

    monkeypatch.setattr(build.shutil, "which", lambda name: None)
    with pytest.raises(build.ToolchainError, match="avr-gcc not found.*apt-get install gcc-avr avr-libc simavr "
                                                   "libsimavr-dev"):
        build.build_firmware(tmp_path)
