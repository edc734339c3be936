"""How fast each installed command answers ``--help``, against a bare ``python -c pass``.

Run with the package installed:  python benchmarks/startup_bench.py [--runs 5]

Prints the best of ``--runs`` wall times per command; the stages (NumPy, SciPy,
OR-Tools, OpenCV, matplotlib) must load only when a command runs, not when it parses.
"""

from __future__ import annotations

import argparse
import platform
import shutil
import subprocess
import sys
import time
from importlib import metadata

COMMANDS = tuple(sorted(ep.name for ep in metadata.distribution("vlp-plan").entry_points if ep.group == "console_scripts"))


def best_of(argv: list[str], runs: int) -> float:
    best = float("inf")
    for _ in range(runs):
        t0 = time.perf_counter()
        subprocess.run(argv, capture_output=True, check=True)
        best = min(best, time.perf_counter() - t0)
    return best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=5)
    args = ap.parse_args()
    print(f"# {platform.machine()}, python {platform.python_version()}, {time.strftime('%Y-%m-%d')}; "
          f"best of {args.runs}")
    print("| command | --help [s] |\n|---|---:|")
    print(f"| python -c pass | {best_of([sys.executable, '-c', 'pass'], args.runs):.2f} |")
    for command in COMMANDS:
        script = shutil.which(command)
        if script is None:
            sys.exit(f"startup_bench: {command} is not installed (pip install .)")
        print(f"| {command} | {best_of([script, '--help'], args.runs):.2f} |", flush=True)


if __name__ == "__main__":
    main()
