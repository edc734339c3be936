"""How fast each installed command answers ``--help`` and refuses a missing file, against a bare ``python -c pass``.

Run with the package installed:  python benchmarks/startup_bench.py [--runs 5]

Prints the best of ``--runs`` wall times per command; the stages (SciPy, OR-Tools, OpenCV,
matplotlib, NetworkX) must load only when a command has checked its input and runs, not when
it parses or refuses (``tests/cli/test_startup.py`` holds the refusals to that).
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


REFUSED = {"vlp-plan": ["missing.yaml"], "vlp-verify": ["missing.yaml"], "vlp-locate": ["missing.yaml"],
           "vlp-report": ["missing.yaml"], "vlp-twin": ["missing.yaml"], "vlp-flash": ["missing.yaml", "--all"],
           "vlp-efficiency": ["missing.yaml"], "vlp-inspect": ["missing.dxf"]}
"""Each command taking a file, given one that does not exist."""


def best_of(argv: list[str], runs: int, ok: bool = True) -> float:
    best = float("inf")
    for _ in range(runs):
        t0 = time.perf_counter()
        done = subprocess.run(argv, capture_output=True)
        if (done.returncode == 0) != ok:
            sys.exit(f"startup_bench: {' '.join(argv)} exited {done.returncode}: {done.stderr.decode()[-200:]}")
        best = min(best, time.perf_counter() - t0)
    return best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=5)
    args = ap.parse_args()
    print(f"# {platform.machine()}, python {platform.python_version()}, {time.strftime('%Y-%m-%d')}; "
          f"best of {args.runs}")
    print("| command | --help [s] | missing file [s] |\n|---|---:|---:|")
    print(f"| python -c pass | {best_of([sys.executable, '-c', 'pass'], args.runs):.2f} | |")
    for command in COMMANDS:
        script = shutil.which(command)
        if script is None:
            sys.exit(f"startup_bench: {command} is not installed (pip install .)")
        refused = f"{best_of([script, *REFUSED[command]], args.runs, ok=False):.2f}" if command in REFUSED else ""
        print(f"| {command} | {best_of([script, '--help'], args.runs):.2f} | {refused} |", flush=True)


if __name__ == "__main__":
    main()
