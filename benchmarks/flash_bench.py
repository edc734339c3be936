"""Benchmark: flashing throughput against the line rate, and the time to flash 512 drivers on a bus.

Run from the repository root:  python benchmarks/flash_bench.py [--drivers 512] [--baud 115200]

Uses the ``sim://`` port with ``paced=1``: every byte takes its line time at the baud
rate (10 bit times) both ways and the driver its programming time (2 ms per block),
so wall time is what a real bus of ideal drivers would take; the host is the real
``vlp-flash`` code (``Link``, ``flash_driver``).

1. Bulk payload throughput: one driver with a 64 KiB slot, a 60 KiB transfer
   (BEGIN, WRITE in 256-byte blocks, VERIFY), payload bytes per second against the
   line's 11,520 bytes/s at 115,200 baud.
2. 512 drivers on one bus, each flashed with its 168-byte signed configuration image
   (HELLO, BEGIN, WRITE, VERIFY, COMMIT, HELLO to confirm).
"""

from __future__ import annotations

import argparse
import hashlib
import os
import platform
import sys
import time
from pathlib import Path

import serial

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from planner.firmware.image import config_image  # noqa: E402
from planner.flash.flasher import flash_driver  # noqa: E402
from planner.flash.link import Link  # noqa: E402
from planner.flash.sim import protocol_sim  # noqa: E402
from planner.flash.wire import BEGIN_REQUEST, VERIFY_REPLY, WRITE_HEAD, Command, Hello  # noqa: E402

KEY = bytes(range(32))


def bulk(baud: int) -> None:
    port = serial.serial_for_url(f"sim://?drivers=1&paced=1&slot_size=65536&key={KEY.hex()}", baudrate=baud,
                                 timeout=0.1)
    link = Link(port, baud)
    hello = Hello.unpack(link.request(1, Command.HELLO).payload)
    blob = os.urandom(60 * 1024)
    sha = hashlib.sha256(blob).digest()
    t0 = time.perf_counter()
    link.request(1, Command.BEGIN, BEGIN_REQUEST.pack(len(blob), 1, sha, 1))
    for offset in range(0, len(blob), hello.max_block):
        link.request(1, Command.WRITE, WRITE_HEAD.pack(offset) + blob[offset:offset + hello.max_block],
                     driver_s=hello.block_write_us * 1e-6)
    staged, digest = VERIFY_REPLY.unpack(link.request(1, Command.VERIFY).payload[:VERIFY_REPLY.size])
    dt = time.perf_counter() - t0
    assert staged == len(blob) and digest == sha
    line = baud / 10
    print(f"bulk: {len(blob)} bytes in {dt:.2f} s = {len(blob) / dt:,.0f} bytes/s, {100 * len(blob) / dt / line:.1f} % "
          f"of the line's {line:,.0f} bytes/s ({hello.max_block}-byte blocks, {hello.block_write_us} us programming "
          f"each); {link.stats.requests} requests, {link.stats.retries} retries")
    port.close()


def bus(n: int, baud: int) -> None:
    port = serial.serial_for_url(f"sim://?drivers={n}&paced=1&key={KEY.hex()}", baudrate=baud, timeout=0.1)
    link = Link(port, baud)
    images = [config_image(f"L{k:04d}", k, "0111000110011010", 12600.0, "0123456789abcdef") for k in range(1, n + 1)]
    t0 = time.perf_counter()
    results = [flash_driver(link, k, image, KEY) for k, image in enumerate(images, 1)]  # signed per driver
    dt = time.perf_counter() - t0
    ok = sum(r.verified for r in results)
    payload = sum(len(i) for i in images)
    print(f"bus: {n} drivers flashed and verified: {ok}; {dt:.1f} s ({1e3 * dt / n:.0f} ms per driver); "
          f"{link.stats.bytes_sent + link.stats.bytes_received:,} bytes on the line for {payload:,} image bytes "
          f"({100 * payload / dt / (baud / 10):.1f} % payload efficiency); {link.stats.retries} retries")
    port.close()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--drivers", type=int, default=512)
    parser.add_argument("--baud", type=int, default=115200)
    args = parser.parse_args()
    protocol_sim.register()
    print(f"# {platform.node()} {platform.processor() or platform.machine()}, {platform.python_version()}, "
          f"{time.strftime('%Y-%m-%d')}, {args.baud} baud")
    bulk(args.baud)
    bus(args.drivers, args.baud)


if __name__ == "__main__":
    main()
