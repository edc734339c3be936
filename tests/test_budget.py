"""The work budget: poses counted as the stages draw them, refused before any work with the numbers."""

from __future__ import annotations

import pytest

from conftest import ROOT, grid32_copy
from planner.cli import plan as plan_cli
from planner.cli import verify as verify_cli
from planner.errors import UsageError
from planner.layout.read import read_layout
from planner.plan import budget
from planner.plan.pipeline import PlanOptions, make_plan
from planner.verify import windows


class _Drawn(Exception):
    """Raised by the spy once make_plan has drawn its one sample: the stages after it are not what is counted."""


def test_the_plan_sample_counted_is_the_one_make_plan_draws(monkeypatch):
    drawn = []
    real = windows.PoseSample.draw.__func__

    def spy(cls, area, xyz, radii, camera, per_m2, seed=0):
        drawn.append(len(real(cls, area, xyz, radii, camera, per_m2, seed).poses))
        raise _Drawn  # make_plan draws once ("every stage takes a prefix"): stop there

    monkeypatch.setattr(windows.PoseSample, "draw", classmethod(spy))
    layout = read_layout(ROOT / "layouts" / "grid-32.yaml", None)
    for per_m2, error in ((400.0, 4.0), (37.0, 0.0), (2000.0, 50.0)):
        with pytest.raises(_Drawn):
            make_plan(layout, PlanOptions(poses_per_m2=per_m2, error_poses_per_m2=error))
        work = budget.plan_work(layout.xy, layout.outline, scheme="auto", verify=True, poses_per_m2=per_m2,
                                error_poses_per_m2=error)
        assert work.samples["plan sample"] == drawn[-1] > 0


def test_work_beyond_the_budget_is_refused_with_its_numbers():
    work = budget.Work({"plan sample": 80_000_000_000, "window design": 160_000_000_000})
    with pytest.raises(UsageError, match=r"240,000,000,000 camera poses \(plan sample 80,000,000,000, window design "
                                         r"160,000,000,000\): about 64,000.0 GB and 467 h, more than the 50,000,000"):
        budget.check_work(work, None)
    with pytest.raises(UsageError, match="more than `max_poses` 10; lower `poses_per_m2` or raise `max_poses`"):
        budget.check_work(budget.Work({"verification": 11}), 10)
    budget.check_work(budget.Work({"verification": 10}), 10)  # at the budget: runs
    budget.check_work(budget.Work({"verification": 60_000_000}), 60_000_000)  # asked for: no default cap


def test_the_memory_check_uses_what_the_machine_has(monkeypatch):
    monkeypatch.setattr(budget, "available_bytes", lambda: 10**9)
    with pytest.raises(UsageError, match=r"but 1.0 GB of memory is available"):
        budget.check_work(budget.Work({"plan sample": 3_000_000}), None)  # 1.2 GB
    budget.check_work(budget.Work({"plan sample": 2_000_000}), None)


@pytest.mark.parametrize("module, argv", [
    (plan_cli, [str(ROOT / "layouts" / "grid-32.yaml"), "--poses-per-m2", "20000", "--max-poses", "1000"]),
    (plan_cli, [str(ROOT / "layouts" / "outline-room.yaml"), "--leds", "128", "--poses-per-m2", "20000",
                "--max-poses", "100000"]),
])
def test_commands_refuse_before_any_work(module, argv, tmp_path, capsys, monkeypatch):
    import planner.plan.pipeline as pipeline

    monkeypatch.setattr(pipeline, "make_plan", lambda *a, **k: pytest.fail("planned beyond the budget"))
    out = tmp_path / "out"
    assert module.console_main([*argv, "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "camera poses" in err and "--max-poses" in err and not out.exists()


def test_vlp_verify_refuses_before_sampling(tmp_path, tmp_path_factory, capsys):
    plan = grid32_copy(tmp_path_factory, tmp_path / "p", "--error-poses-per-m2", "0")  # planned once per run
    assert verify_cli.console_main([str(plan), "--poses-per-m2", "20000", "--max-poses", "100"]) == 2
    assert "verification 160,000" in capsys.readouterr().err
