"""``vlp-plan --timings`` prints each stage's time after the summary; stages are announced on a terminal only,
never with ``--json`` and never into a pipe or a CI log."""

import json
import os
import pty
import re
import subprocess

from conftest import ROOT, vlp

GRID = str(ROOT / "layouts" / "grid-32.yaml")
TIMING = re.compile(r"^vlp-plan: timing +(\d+\.\d\d) s  (.+)$")
STAGES = ["reading", "pose sampling", "IDs and verification", "frames", "error map",
          "advice", "plan.yaml", "firmware", "annotated drawing", "maps", "site report", "total"]


def run_on_a_terminal(argv: list[str]) -> tuple[int, str, str]:
    """Run ``argv`` with stderr on a pseudo-terminal (as in a shell); return exit code, stdout, stderr."""
    main, other = pty.openpty()
    done = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=other, text=True)
    os.close(other)
    err = b""
    while True:
        try:
            chunk = os.read(main, 4096)
        except OSError:  # the child closed the terminal
            break
        if not chunk:
            break
        err += chunk
    out = done.communicate(timeout=600)[0]
    os.close(main)
    return done.returncode, out, err.decode().replace("\r\n", "\n")


def test_timings_print_a_line_per_stage_after_the_summary(tmp_path):
    code, out, err = run_on_a_terminal(["vlp-plan", GRID, "-o", str(tmp_path / "plan"), "--timings"])
    assert code == 0, err
    assert out.startswith("vlp-plan ") and "wrote" in out  # the summary, on stdout
    lines = err.splitlines()
    timings = [TIMING.match(line) for line in lines if line.startswith("vlp-plan: timing")]
    assert [m.group(2) for m in timings if m] == STAGES  # every line well formed, each stage once, in order
    seconds = {m.group(2): float(m.group(1)) for m in timings if m}
    assert seconds["total"] > 0 and sum(v for k, v in seconds.items() if k != "total") <= seconds["total"] + 0.05
    assert lines[-len(STAGES):] == [m.group(0) for m in timings if m]  # the timings come last
    progress = [line for line in lines if line.startswith("  .. ")]
    assert progress[0] == f"  .. reading: {GRID}" and "  .. error map: at most 1000 poses" in progress
    assert len(progress) == len(STAGES) - 1  # each stage announced as it starts, on the terminal


def test_json_and_pipes_stay_quiet(tmp_path):
    code, out, err = run_on_a_terminal(["vlp-plan", GRID, "-o", str(tmp_path / "a"), "--json", "--no-verify",
                                        "--scheme", "paper", "--no-report", "--no-firmware"])
    assert code == 0 and json.loads(out)["luminaires"] == 32
    assert err == ""  # a terminal, but --json: no progress
    done = vlp("vlp-plan", GRID, "-o", str(tmp_path / "b"), "--no-verify", "--scheme", "paper",
               "--no-report", "--no-firmware")
    assert done.returncode == 0 and done.stderr == ""  # a pipe (CI log): no progress, and no timings unasked
