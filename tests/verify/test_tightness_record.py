"""plan.yaml records how tight the proved window set is: its size beside the windows the plan's own sample found."""
import json

import yaml

from conftest import ROOT
from planner.cli.plan import main


def test_plan_records_the_proved_set_beside_the_sampled_windows(tmp_path, capsys):
    code = main([str(ROOT / "layouts" / "grid-32.yaml"), "-o", str(tmp_path / "out"), "--json", "--scheme", "window",
                 "--no-report", "--no-firmware", "--no-map"])
    assert code == 0
    v = json.loads(capsys.readouterr().out)["verification"]
    ws = v["window_set"]
    assert ws["complete"] and ws["sampled_windows"] == v["windows"] > 0
    assert ws["triangles"] >= ws["sampled_windows"]  # a proved superset of what a sample finds
    assert ws["over_sampled"] == round(ws["triangles"] / ws["sampled_windows"], 2)
    doc = yaml.safe_load((tmp_path / "out" / "plan.yaml").read_text())
    keys = list(doc["verification"]["window_set"])
    assert keys.index("sampled_windows") == keys.index("triangles") + 1
