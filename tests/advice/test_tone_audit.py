"""planner.advice.tones: the retune a clash is advised, and the audit's summary."""

import numpy as np

from planner.advice.tones import audit_tones, clash_text, retune


def test_retune_to_the_nearest_tone_apart_from_every_tone_of_the_site():
    tones = np.array([2000.0, 2500.0, 3000.0, 3000.0, 3500.0, 4000.0])
    r = retune(3, tones, {2, 4}, 60.0, 200.0, 10_000.0)
    # on 30-row images (half the smallest) 2,800 Hz reads apart from 3,000 (200 > 5,800 / 30 = 193 Hz) and 2,500;
    # 2,850 (150 < 195 Hz) and 3,200 (200 < 207 Hz) do not
    assert r is not None and r.index == 3 and r.tone_hz == 2800.0 and r.unique


def test_retune_falls_back_to_the_window_neighbours_then_gives_up():
    tones = np.array([2000.0, 2000.0, 2050.0, 2100.0])
    r = retune(1, tones, {0}, 1000.0, 2000.0, 2100.0)  # every grid tone is taken somewhere on the site
    assert r is not None and r.tone_hz == 2050.0 and not r.unique
    assert retune(1, tones, {0, 2, 3}, 1000.0, 2000.0, 2100.0) is None


def test_audit_summary_names_the_clash_and_counts_its_poses():
    tones = np.array([2000.0, 2000.0, 3000.0, 4000.0])
    classes = np.array([1, 1, 2, 3])
    windows = np.array([[0, 1, 2], [0, 2, 3], [1, 0, 3], [1, 2, 3]])
    seen = np.array([True, True, True, False])
    positions = np.array([[1.0, 2.0, 1.2], [5.0, 5.0, 1.2], [3.0, 4.0, 1.2], [0.0, 0.0, 1.2]])
    audit = audit_tones(tones, classes, 100.0, 20e-6, 20_000.0, windows, seen, positions)
    s = audit.summary(["A", "B", "C", "D"])
    assert s["sampled_poses"] == 4 and s["ambiguous_poses"] == 2 and s["tone_classes"] == 3
    assert s["lowest_readable_hz"] == 500.0 and s["highest_hz"] == 10_000.0
    (c,) = s["clashes"]
    assert c["luminaires"] == ["A", "B"] and c["poses"] == 2 and c["around_m"] == [2.0, 3.0]
    assert c["from_m"] == [1.0, 2.0] and c["to_m"] == [3.0, 4.0]
    assert c["retune"]["luminaire"] == "B"
    line = clash_text(c, 4)
    assert line.startswith("AMBIGUOUS A (2000 Hz) and B (2000 Hz) share the window of 2 of 4 sampled poses, "
                           "around (2.00, 3.00) m")
    assert f"retune B to {c['retune']['to_hz']:g} Hz" in line
    assert audit.first_clash(["A", "B", "C", "D"]) == line


def test_retunes_are_joint_not_each_against_the_old_site():
    # three LEDs of one tone in one window: each retune must also keep apart from the retunes before it
    tones = np.full(3, 2000.0)
    audit = audit_tones(tones, np.ones(3, dtype=int), 100.0, 20e-6, 20_000.0, np.array([[0, 1, 2]]),
                        np.array([True]), np.zeros((1, 3)))
    s = audit.summary(["A", "B", "C"])
    assert [c["luminaires"] for c in s["clashes"]] == [["A", "B"], ["A", "C"], ["B", "C"]]
    assert s["clashes"][0]["retune"]["to_hz"] == 1900.0  # 100 Hz > (2000 + 1900) / 50; 1,950 Hz is not apart
    assert s["clashes"][1]["retune"]["to_hz"] == 2100.0  # apart from 2,000 and from B's new 1,900 Hz
    assert "retune" not in s["clashes"][2] and s["clashes"][2]["settled_by_earlier_retunes"]
    assert clash_text(s["clashes"][2], 1).endswith("; the retunes above settle it")
