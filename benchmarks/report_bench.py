"""Benchmark: time to write the site report (HTML and PDF) for 512 and about 10,000 luminaires.

Run from the repository root:  python benchmarks/report_bench.py [--tiles 20]

Plans the bundled 512 grid once (maps included, no report), then times
``write_report`` on it and on a site made of ``--tiles`` copies of it stacked
in y (10,240 luminaires by default: planning that many for real takes a
minute and does not change the report's work, which grows with the number of
luminaires). Prints seconds, PDF pages and file sizes.
"""

from __future__ import annotations

import argparse
import platform
import re
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from planner.layout.read import read_layout  # noqa: E402
from planner.plan.file import PlanFile, load_plan, plan_from_document  # noqa: E402
from planner.plan.pipeline import PlanOptions, make_plan, write_outputs  # noqa: E402
from planner.report.files import write_report  # noqa: E402


def _pages(pdf: Path) -> int:
    return len(re.findall(rb"/Type\s*/Page\b", pdf.read_bytes()))


def _time(doc: PlanFile, plan_dir: Path, out: Path, label: str) -> None:
    t0 = time.perf_counter()
    html, pdf = write_report(doc, "0" * 16, plan_dir, out)
    dt = time.perf_counter() - t0
    print(f"{label:<28} {len(doc.luminaires):>6} luminaires  {dt:6.2f} s  {_pages(pdf):>4} PDF pages  "
          f"HTML {html.stat().st_size / 1e6:5.2f} MB  PDF {pdf.stat().st_size / 1e6:5.2f} MB")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tiles", type=int, default=20, help="copies of the 512 grid in the large site (default 20)")
    args = ap.parse_args()
    print(f"python {platform.python_version()} on {platform.machine()}, {platform.node()}")
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        plan = make_plan(read_layout(ROOT / "layouts" / "grid-512.yaml", 512), PlanOptions())
        write_outputs(plan, tmp / "plan", with_report=False, firmware=None)
        doc = load_plan(tmp / "plan" / "plan.yaml")
        write_report(doc, "0" * 16, tmp / "plan", tmp / "warm")  # imports and font caches
        _time(doc, tmp / "plan", tmp / "r512", "grid-512")
        span = max(e.y for e in doc.luminaires) + 0.5
        raw = doc.document()
        raw["luminaires"] = [dict(e, name=f"{e['name']}-{k}", y=e["y"] + k * span)
                             for k in range(args.tiles) for e in raw["luminaires"]]
        raw["outline"] = None
        big = plan_from_document(raw, "stacked plan")
        _time(big, tmp / "plan", tmp / "rbig", f"grid-512 x {args.tiles} (stacked)")


if __name__ == "__main__":
    main()
