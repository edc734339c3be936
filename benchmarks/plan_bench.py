"""Whole ``vlp-plan`` per bundled layout and a 48-luminaire office: CPU, wall time and peak memory.

Run from the repository root, with the package installed (the installed ``vlp-plan`` is timed):

    python benchmarks/plan_bench.py [--only NAME ...] [--list]

Each case is one ``vlp-plan`` child process writing every output (plan, DXF, maps, site report, firmware)
into a temporary directory; its CPU time (user + system) and peak resident memory come from
``os.wait4`` (that child's own rusage), so other work on a shared machine inflates the wall time
but hardly the CPU time. Prints a Markdown table for docs/performance.md (issue 38's aims: under
10 s each, aim 3 s, peak under 1 GB).
"""

from __future__ import annotations

import argparse
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
LAYOUTS = ROOT / "layouts"

OFFICE_PITCH_M, OFFICE_COLS, OFFICE_ROWS, OFFICE_HEIGHT_M = 2.4, 8, 6, 2.8


def office_yaml(path: Path) -> Path:
    """An 8 x 6 office lattice at 2.4 m pitch under a 2.8 m ceiling (48 luminaires), its room as the outline."""
    w, h = OFFICE_COLS * OFFICE_PITCH_M, OFFICE_ROWS * OFFICE_PITCH_M
    lines = ["unit: m", f"height: {OFFICE_HEIGHT_M}", "radius: 0.1", "outline:",
             "- [0, 0]", f"- [{w:g}, 0]", f"- [{w:g}, {h:g}]", f"- [0, {h:g}]", "luminaires:"]
    lines += [f"- {{name: R{r + 1:02d}C{c + 1:02d}, x: {(c + 0.5) * OFFICE_PITCH_M:g}, y: {(r + 0.5) * OFFICE_PITCH_M:g}}}"
              for r in range(OFFICE_ROWS) for c in range(OFFICE_COLS)]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def cases(office: Path) -> dict[str, list[str]]:
    """Name -> vlp-plan arguments: every bundled layout as the README plans it, and the office."""
    fisheye = ["--camera", "ultrawide-fisheye", "--receiver", "gravity", "--driver-max-hz", "50000"]
    return {
        "paper-rig": [str(LAYOUTS / "paper-rig.yaml")],
        "corridor": [str(LAYOUTS / "corridor.csv")],
        "grid-32": [str(LAYOUTS / "grid-32.yaml")],
        "grid-256": [str(LAYOUTS / "grid-256.yaml")],
        "grid-512": [str(LAYOUTS / "grid-512.yaml"), "--leds", "512"],
        "outline-room.yaml 512": [str(LAYOUTS / "outline-room.yaml"), "--leds", "512"],
        "outline-room.dxf 128": [str(LAYOUTS / "outline-room.dxf"), "--leds", "128"],
        "dialux-office": [str(LAYOUTS / "dialux-office.dxf")],
        "dialux-office fisheye gravity": [str(LAYOUTS / "dialux-office.dxf"), *fisheye],
        "office-48": [str(office)],
        "office-48 gravity": [str(office), "--receiver", "gravity"],
    }


def run(args: list[str], outdir: Path) -> tuple[int, float, float, float]:
    """Exit code, CPU [s], wall [s] and peak resident memory [MiB] of one ``vlp-plan`` child."""
    exe = shutil.which("vlp-plan") or sys.exit("vlp-plan is not installed: pip install . first")
    t0 = time.perf_counter()
    child = subprocess.Popen([exe, *args, "-o", str(outdir)], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(child.pid, 0)
    wall = time.perf_counter() - t0
    child.returncode = os.waitstatus_to_exitcode(status)
    err = child.stderr.read().decode() if child.stderr else ""
    if child.returncode not in (0, 3):
        print(f"  exit {child.returncode}: {err.strip().splitlines()[-1] if err.strip() else ''}", file=sys.stderr)
    return child.returncode, usage.ru_utime + usage.ru_stime, wall, usage.ru_maxrss / 1024


def receiver(outdir: Path) -> str:
    """The receiver mode the plan in ``outdir`` was made for, and the modes planned to choose it."""
    import yaml

    plan = outdir / "plan.yaml"
    if not plan.is_file():
        return "-"
    r = yaml.safe_load(plan.read_text()).get("receiver") or {"mode": "three"}
    others = [m for m in r.get("coverage", {}) if m != r["mode"]]
    return r["mode"] + (f" (of {', '.join([r['mode'], *others])})" if others else "")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", nargs="+", metavar="NAME", help="run only these cases (see --list)")
    parser.add_argument("--list", action="store_true", help="list the cases and exit")
    parser.add_argument("--keep", type=Path, metavar="DIR", help="write the outputs under DIR and keep them")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="plan-bench-") as tmp:
        outs = args.keep or Path(tmp)
        todo = cases(office_yaml(Path(tmp) / "office-48.yaml"))
        if args.list:
            print("\n".join(f"{name}: vlp-plan {' '.join(a)}" for name, a in todo.items()))
            return
        load = os.getloadavg()[0]
        print(f"# {platform.node()} {platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}, "
              f"{time.strftime('%Y-%m-%d %H:%M', time.gmtime())} UTC, load {load:.1f} at start")
        print("| case | receiver | exit | CPU [s] | wall [s] | peak [MiB] |\n|---|---|---:|---:|---:|---:|")
        for name, a in todo.items():
            if args.only and name not in args.only:
                continue
            out = outs / name.replace(" ", "_")
            code, cpu, wall, peak = run(a, out)
            print(f"| {name} | {receiver(out)} | {code} | {cpu:.1f} | {wall:.1f} | {peak:,.0f} |", flush=True)
        print(f"load {os.getloadavg()[0]:.1f} at the end")


if __name__ == "__main__":
    main()
