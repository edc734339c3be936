"""The audit of an existing tone site: what the camera tells apart, where two luminaires clash, what to retune.

Made by :func:`audit_tones` from the kept tones, the plan's sampled windows and the smallest LED
image of a window; written into ``plan.yaml`` (``tones``) and the summary. docs/tones.md.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from planner.defaults import FLICKER_HZ
from planner.modulation.tones import highest_tone_hz, lowest_readable_hz, tones_apart
from planner.verify.tones import ToneClash, shared_windows, tone_clashes

RULE = "f2 - f1 > (f1 + f2) / rows"
"""When the camera tells two tones apart (planner.modulation.tones)."""

RETUNE_STEP_HZ = 50.0
"""Grid of the tones a retune suggests [Hz]."""

DRIVERS = "tone drivers are configured outside vlp-plan: no frames or firmware are written for a tone site"


@dataclass(frozen=True)
class Retune:
    """Retune luminaire ``index`` to ``tone_hz`` [Hz]; ``unique``: apart from every tone of the site, else only
    from those it shares a window with."""

    index: int
    tone_hz: float
    unique: bool


@dataclass(frozen=True)
class ToneAudit:
    """A tone site as the camera reads it (tones [Hz], rows of the smallest LED image, row time [s])."""

    tones_hz: np.ndarray
    classes: np.ndarray
    rows: float
    row_time_s: float
    highest_hz: float
    highest_limit: str
    poses: int
    clash_poses: int
    clashes: list[ToneClash]
    retunes: list[Retune | None]  # None: no free tone, or the retunes of earlier clashes settle this one
    settled: list[bool]  # the retunes of earlier clashes already tell this pair apart

    def summary(self, names: list[str]) -> dict:
        low = lowest_readable_hz(self.rows, self.row_time_s)
        return {
            "rule": RULE,
            "smallest_image_rows": round(self.rows, 3),
            "row_time_s": self.row_time_s,
            "lowest_readable_hz": round(low, 1),
            "below_one_period": [n for n, f in zip(names, self.tones_hz) if f < low],
            "highest_hz": round(self.highest_hz, 1),
            "highest_limit": self.highest_limit,
            "tones": int(len(np.unique(self.tones_hz))),
            "tone_classes": int(self.classes.max()),
            "sampled_poses": self.poses,
            "ambiguous_poses": self.clash_poses,
            "clashes": [{
                "luminaires": [names[c.a], names[c.b]],
                "tones_hz": [float(self.tones_hz[c.a]), float(self.tones_hz[c.b])],
                "poses": c.poses,
                "around_m": [round(v, 3) for v in c.centre_xy],
                "from_m": [round(v, 3) for v in c.low_xy],
                "to_m": [round(v, 3) for v in c.high_xy],
                **({"retune": {"luminaire": names[r.index], "to_hz": r.tone_hz, "apart_from": (
                    "every tone of the site" if r.unique else "the tones it shares a window with")}}
                   if (r := self.retunes[k]) is not None else {}),
                **({"settled_by_earlier_retunes": True} if self.settled[k] else {}),
            } for k, c in enumerate(self.clashes)],
            "drivers": DRIVERS,
        }


    def first_clash(self, names: list[str]) -> str:
        """The clash seen from the most sampled poses, where it is and what to do (one line)."""
        return clash_text(self.summary(names)["clashes"][0], self.poses)


def audit_tones(tones_hz: np.ndarray, classes: np.ndarray, rows: float, row_time_s: float, driver_max_hz: float,
                windows: np.ndarray, seen: np.ndarray, positions: np.ndarray) -> ToneAudit:
    """The clashes over the sampled windows (``windows`` (P, k), ``seen`` (P,), camera ``positions`` (P, 3) [m])
    and a retune for each."""
    high, why = highest_tone_hz(row_time_s, driver_max_hz)
    clashes = tone_clashes(windows, seen, classes, positions)
    sharers = shared_windows(windows, seen, len(tones_hz))
    low = max(FLICKER_HZ, lowest_readable_hz(rows, row_time_s))
    tuned = tones_hz.astype(float).copy()  # the site as the retunes so far leave it: they must not clash either
    retunes: list[Retune | None] = []
    settled = []
    for c in clashes:
        settled.append(bool(tones_apart(tuned[c.a], tuned[c.b], rows)))
        r = None if settled[-1] else retune(c.b, tuned, sharers[c.b], rows, low, high)
        if r is not None:
            tuned[r.index] = r.tone_hz
        retunes.append(r)
    hit = np.zeros(len(seen), dtype=bool)
    w = np.asarray(windows, dtype=np.int64).reshape(len(seen), -1)
    for i in range(w.shape[1]):
        for j in range(i + 1, w.shape[1]):
            hit |= seen & (classes[w[:, i]] == classes[w[:, j]])
    return ToneAudit(tones_hz, classes, rows, row_time_s, high, why, len(seen), int(hit.sum()), clashes, retunes,
                     settled)


def retune(index: int, tones_hz: np.ndarray, sharers: set[int], rows: float, low_hz: float, high_hz: float
           ) -> Retune | None:
    """The tone nearest luminaire ``index``'s own, on a ``RETUNE_STEP_HZ`` grid within ``low_hz``..``high_hz``, that
    the camera tells apart with a factor 2 to spare (on images half the smallest) from every tone of the site, else
    from the tones of the luminaires it shares a window with (``sharers``); None if no tone is free."""
    grid = np.arange(np.ceil(low_hz / RETUNE_STEP_HZ), np.floor(high_hz / RETUNE_STEP_HZ) + 1) * RETUNE_STEP_HZ
    grid = grid[np.argsort(np.abs(grid - tones_hz[index]), kind="stable")]
    others = np.delete(np.arange(len(tones_hz)), index)
    for unique, group in ((True, others), (False, np.array(sorted(sharers), dtype=np.int64))):
        ok = np.all(tones_apart(grid[:, None], tones_hz[group][None, :], rows / 2), axis=1)
        if ok.any():
            return Retune(index, float(grid[np.argmax(ok)]), unique)
    return None


def tone_lines(s: dict, names_limit: int = 5) -> list[str]:
    """The summary's lines for a tone site (``s``: :meth:`ToneAudit.summary`)."""
    n, k = s["tones"], s["tone_classes"]
    lines = [f"tones    {n} tone{'s' if n != 1 else ''} in {k} class{'es' if k != 1 else ''} the camera tells apart "
             f"({s['rule']}, "
             f"smallest LED image {s['smallest_image_rows']:.0f} rows of {s['row_time_s'] * 1e6:g} us); readable "
             f"{s['lowest_readable_hz']:,.0f}..{s['highest_hz']:,.0f} Hz"]
    if s["below_one_period"]:
        lines.append(f"         below one period in the smallest image (read only from nearer): "
                     f"{', '.join(s['below_one_period'][:names_limit])}")
    for c in s["clashes"][:names_limit]:
        lines.append("         " + clash_text(c, s["sampled_poses"]))
    if not s["clashes"]:
        lines.append("         no two luminaires of one tone class share a sampled window")
    lines.append(f"         {s['drivers']}")
    return ["  " + line for line in lines]


def clash_text(c: dict, poses: int) -> str:
    """One clash, where it is and what to do."""
    a, b = c["luminaires"]
    fa, fb = c["tones_hz"]
    text = (f"AMBIGUOUS {a} ({fa:g} Hz) and {b} ({fb:g} Hz) share the window of {c['poses']} of {poses} sampled "
            f"poses, around ({c['around_m'][0]:.2f}, {c['around_m'][1]:.2f}) m (x {c['from_m'][0]:.2f}..{c['to_m'][0]:.2f}, "
            f"y {c['from_m'][1]:.2f}..{c['to_m'][1]:.2f}): a tone receiver cannot tell them apart there")
    r = c.get("retune")
    return text + (f"; retune {r['luminaire']} to {r['to_hz']:g} Hz (apart from {r['apart_from']})" if r
                   else "; the retunes above settle it" if c.get("settled_by_earlier_retunes")
                   else "; no free tone within the limits: move one of them or switch one off")
