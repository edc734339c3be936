"""A refusal is quick (issue 35): every command reads its flags and checks its inputs (a missing file, a file
that is not YAML or not a plan, a bad flag) before it loads the heavy stages, so it refuses in about 0.2 s of
CPU, not the 1.3 s that importing SciPy, Matplotlib, OR-Tools, NetworkX and OpenCV costs.

Each case runs the installed console script under ``python -X importtime``, which lists every module the
process imported, and fails on any heavy package among them.
"""

import re
import shutil
import subprocess
import sys

import pytest

from conftest import ROOT

HEAVY = ("matplotlib", "scipy", "ortools", "networkx", "ezdxf", "cv2", "numba", "shapely", "ifcopenshell", "jinja2")
"""Packages a refusal must not import: each costs tens to hundreds of milliseconds of CPU."""

NOT_A_PLAN = "format: vlp-plan/1\nluminaires: abc\n"
NOT_YAML = "luminaires: [\n"

CASES = {  # name -> (command and arguments, files to write first, the error's start)
    "plan-missing-file": (["vlp-plan", "missing.yaml"], {}, "missing.yaml: no such file"),
    "plan-not-yaml": (["vlp-plan", "bad.yaml"], {"bad.yaml": NOT_YAML}, "bad.yaml: line 2: not valid YAML"),
    "plan-bad-flag": (["vlp-plan", "missing.yaml", "--leds", "0"], {}, "argument --leds"),
    "plan-bad-camera": (["vlp-plan", str(ROOT / "layouts" / "grid-32.yaml"), "--camera", "nonesuch"], {},
                        "--camera nonesuch"),
    "plan-wrong-count": (["vlp-plan", str(ROOT / "layouts" / "grid-32.yaml"), "--leds", "33"], {},
                         "found 32 luminaires but --leds says 33"),
    "from-plan-missing": (["vlp-plan", "--from-plan", "missing.yaml"], {}, "missing.yaml"),
    "verify-missing-file": (["vlp-verify", "missing.yaml"], {}, "missing.yaml"),
    "verify-not-a-plan": (["vlp-verify", "plan.yaml"], {"plan.yaml": NOT_A_PLAN}, "plan.yaml: scheme: is missing"),
    "report-not-a-plan": (["vlp-report", "plan.yaml"], {"plan.yaml": NOT_A_PLAN}, "plan.yaml: scheme: is missing"),
    "twin-not-a-plan": (["vlp-twin", "plan.yaml", "--poses", "2"], {"plan.yaml": NOT_A_PLAN},
                        "plan.yaml: scheme: is missing"),
    "locate-not-a-plan": (["vlp-locate", "plan.yaml", "--simulate", "1,1,1,0,0,0"], {"plan.yaml": NOT_A_PLAN},
                          "plan.yaml: scheme: is missing"),
    "flash-not-a-plan": (["vlp-flash", "plan.yaml", "--all", "--dry-run"], {"plan.yaml": NOT_A_PLAN},
                         "plan.yaml: scheme: is missing"),
    "efficiency-not-a-plan": (["vlp-efficiency", "plan.yaml", "--sizes", "16"], {"plan.yaml": NOT_A_PLAN},
                              "plan.yaml: scheme: is missing"),
    "inspect-missing-file": (["vlp-inspect", "missing.dxf"], {}, "missing.dxf"),
    "accuracy-missing-camera": (["vlp-accuracy", "--camera", "missing.yaml"], {}, "missing.yaml"),
}


DRAWING_CASES = {  # a drawing needs ezdxf to be read at all, and no more to be refused
    "plan-not-a-dxf": (["vlp-plan", "fake.dxf"], {"fake.dxf": "not a drawing\n"}, "fake.dxf: not a DXF file"),
}


def imported(stderr: str) -> set[str]:
    """The top-level packages ``-X importtime`` says the process imported."""
    return {m[1].split(".")[0] for m in re.finditer(r"^import time:[^|]*\|[^|]*\|\s*(\S+)$", stderr, re.M)}


@pytest.mark.parametrize("case", sorted(CASES) + sorted(DRAWING_CASES))
def test_a_refusal_loads_no_heavy_stage(tmp_path, case):
    argv, files, error = CASES[case] if case in CASES else DRAWING_CASES[case]
    heavy = set(HEAVY) - ({"ezdxf"} if case in DRAWING_CASES else set())
    for name, text in files.items():
        (tmp_path / name).write_text(text, "utf-8")
    done = subprocess.run([sys.executable, "-X", "importtime", shutil.which(argv[0]), *argv[1:]],
                          capture_output=True, text=True, cwd=tmp_path, timeout=60)
    lines = [line for line in done.stderr.splitlines() if not line.startswith("import time:")]
    assert done.returncode in (1, 2) and len(lines) == 1 and error in lines[0], done.stderr[-2000:]
    modules = imported(done.stderr)
    assert "planner" in modules, sorted(modules)  # the list is read right: the command itself is there
    assert not modules & heavy, f"{argv[0]} imported {sorted(modules & heavy)} to refuse: {lines[0]}"
