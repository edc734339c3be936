"""Big and hostile DXF drawings: wall time, CPU time and peak memory of the installed commands (issue 36).

Run from the repository root, with the package installed:

    python benchmarks/dxf_bench.py [--only NAME ...] [--list]

Each case is one child process (``vlp-inspect`` or ``vlp-plan`` without verification, report, maps or
firmware, so the reading and the annotated copy dominate); its CPU time and peak resident memory come from
``os.wait4``. Drawings are written as DXF text (ezdxf makes the small part, the many entities are spliced in).
Prints a Markdown table for docs/performance.md.
"""

from __future__ import annotations

import argparse
import io
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

import ezdxf

ROOT = Path(__file__).resolve().parent.parent
sys.path[:0] = [str(ROOT), str(ROOT / "tests")]  # the package, and the drawings the tests build

from dxf_factory import nested_blocks  # noqa: E402
from planner.layout.dxf_load import MAX_DXF_ENTITIES  # noqa: E402

FAST = ["--scheme", "unique", "--no-verify", "--no-report", "--no-map", "--no-firmware"]


def nested(path: Path, levels: int, _kind: str = "nested") -> Path:
    """Blocks nesting blocks, ten references a level, around one luminaire circle: ``10**levels`` luminaires."""
    return nested_blocks(path, "circle", levels)


def drawing(path: Path, extra: int, kind: str, insunits: int = 4) -> Path:
    """48 circles on LIGHTS 2.4 m apart (mm) and ``extra`` spliced entities: tiny LINEs on FURNITURE, POINTs on
    LIGHTS 2.4 m apart (luminaires), or ``dense`` circles 0.6 m apart in metres (no luminaires of the 48)."""
    doc = ezdxf.new("R2010")
    doc.header["$INSUNITS"] = 6 if kind == "dense" else insunits
    msp = doc.modelspace()
    if kind != "dense":
        for i in range(8):
            for j in range(6):
                msp.add_circle((2400 * i, 2400 * j, 2800), 100, dxfattribs={"layer": "LIGHTS"})
    owner = msp.block_record_handle
    handles = [doc.entitydb.handles.next() for _ in range(extra)]
    stream = io.StringIO()
    doc.write(stream)
    text = stream.getvalue()
    end = text.index("\n  0\nENDSEC", text.index("ENTITIES"))
    head = "\n  0\n{kind}\n  5\n{h}\n330\n" + owner + "\n100\nAcDbEntity\n  8\n{layer}\n100\n"
    side = int(extra ** 0.5) + 1
    body = []
    for k, h in enumerate(handles):
        i, j = k % side, k // side
        if kind == "line":
            body.append(head.format(kind="LINE", h=h, layer="FURNITURE")
                        + f"AcDbLine\n 10\n{i * 30}\n 20\n{j * 30}\n 30\n0\n 11\n{i * 30 + 5}\n 21\n{j * 30}\n 31\n0")
        elif kind == "point":
            body.append(head.format(kind="POINT", h=h, layer="LIGHTS")
                        + f"AcDbPoint\n 10\n{i * 2400}\n 20\n{j * 2400}\n 30\n2800")
        else:
            body.append(head.format(kind="CIRCLE", h=h, layer="LIGHTS")
                        + f"AcDbCircle\n 10\n{i * 0.6:g}\n 20\n{j * 0.6:g}\n 30\n2.8\n 40\n0.1")
    path.write_text(text[:end] + "".join(body) + text[end:])
    return path


CASES = {
    "lines-100000 inspect": ("line", 100_000, "vlp-inspect", []),
    "lines-100000 plan": ("line", 100_000, "vlp-plan", FAST),
    "points-100000 inspect": ("point", 100_000, "vlp-inspect", []),
    "points-over-cap plan": ("point", MAX_DXF_ENTITIES, "vlp-plan", FAST),
    "nested-blocks-10^7 inspect": ("nested", 7, "vlp-inspect", []),
    "dense-20164-m plan": ("dense", 20_164, "vlp-plan", FAST),
    "dense-20164-m --units mm": ("dense", 20_164, "vlp-plan", ["--units", "mm", *FAST]),
}
"""Case -> (entities spliced, how many, command, flags)."""


def run(name: str, folder: Path) -> str:
    kind, count, command, flags = CASES[name]
    path = (nested if kind == "nested" else drawing)(folder / f"{kind}-{count}.dxf", count, kind)
    argv = [str(path), *(["-o", str(folder / "out")] if command == "vlp-plan" else []), *flags]
    exe = str(Path(sys.executable).parent / command)
    with open(folder / "stderr", "w") as err, open(folder / "stdout", "w") as out:
        start = time.perf_counter()
        pid = os.posix_spawn(exe, [command, *argv], os.environ,
                             file_actions=[(os.POSIX_SPAWN_DUP2, out.fileno(), 1), (os.POSIX_SPAWN_DUP2, err.fileno(), 2)])
        _, status, usage = os.wait4(pid, 0)
        wall = time.perf_counter() - start
    code = os.waitstatus_to_exitcode(status)
    said = (folder / "stderr").read_text().splitlines() + (folder / "stdout").read_text().splitlines()
    last = ([line for line in said if "error" in line or "would stop" in line] or [""])[-1]
    outcome = ("read" if command == "vlp-inspect" else "planned") if code == 0 else f"exit {code}: {last.split(': ', 2)[-1][:60]}..."
    size = path.stat().st_size / 1e6
    return (f"| {name} | {size:.0f} MB | {wall:.1f} | {usage.ru_utime + usage.ru_stime:.1f} | "
            f"{usage.ru_maxrss / 1024:.0f} | {outcome} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", nargs="+", metavar="NAME", help="cases to run (see --list)")
    parser.add_argument("--list", action="store_true", help="list the cases and stop")
    args = parser.parse_args()
    if args.list:
        print("\n".join(CASES))
        return
    names = args.only or list(CASES)
    print(f"# {platform.node()} {platform.machine()}, Python {platform.python_version()}, "
          f"{time.strftime('%Y-%m-%d %H:%M')}, {os.cpu_count()} cores, load {os.getloadavg()[0]:.1f}")
    print("| case | file | wall [s] | CPU [s] | peak [MiB] | outcome |\n|---|---|---|---|---|---|")
    for name in names:
        with tempfile.TemporaryDirectory() as tmp:
            print(run(name, Path(tmp)), flush=True)


if __name__ == "__main__":
    main()
