"""The issues' Done-when runs at their full size, with their assertions: the 300-pose twins (issues 8, 18
and 19), the twenty 33 MP photos of each site (issue 37), issue 34's large sites and its adversarial samples (80,000
poses per push), issue 13's five dense samples and the 512 drivers flashed over one faulty bus.

Run from the repository root, with the package installed:  python benchmarks/acceptance.py [pytest options]

The suite (``pytest``) runs a smaller sibling of each with the same assertions (30 poses, 2 photos, a smaller
site of the same kind, 16,000 poses per push, one sample, grid-32's 32 drivers) and deselects these. This runs
the tests marked ``acceptance`` (``pytest --acceptance -m acceptance``) on every core, prints what each measured
and how long it took, and exits as pytest does: non-zero when any Done-when no longer holds.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def main() -> int:
    pytest = Path(sys.executable).with_name("pytest")  # this environment's, against the installed package
    if not pytest.is_file():
        sys.exit(f"acceptance: {pytest} not found: install the package with its tests in this environment "
                 "(pip install '.[test]')")
    return subprocess.call([str(pytest), "tests", "--acceptance", "-m", "acceptance", "-n", "auto", "--dist", "loadfile",
                            "-q", "-rP", "--durations=0", "--durations-min=1", *sys.argv[1:]], cwd=ROOT)


if __name__ == "__main__":
    sys.exit(main())
