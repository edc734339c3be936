"""Which receiver mode serves a site: the one asked for, or with ``auto`` (the default) the paper's three-LED
receiver wherever its plan is usable, and where it is not the other modes too, keeping the mode that decodes
more poses (docs/schemes.md, "Receiver modes"). The modes: :mod:`planner.receivers.modes`.
"""

from __future__ import annotations

from dataclasses import dataclass

from planner.defaults import USABLE_COVERAGE
from planner.errors import UsageError
from planner.receivers.base import Job, Planned, Receiver
from planner.receivers.modes import AUTO, PAPER, RECEIVERS, receiver_for
from planner.verify.windows import PoseWindows

AUTO_GOAL = USABLE_COVERAGE
"""``--receiver auto`` plans the other modes too where the three-LED one decodes fewer poses than this: where
its plan is NOT USABLE. Above it the paper's receiver is kept, and the advice says what another mode would add."""


def seen_shares(windows: PoseWindows) -> dict:
    """Shares of sampled poses by what they see: a three-LED window, two or more whole LEDs, exactly one."""
    n = max(len(windows.seen), 1)
    return {"three_led_window": round(float(windows.covered.sum()) / n, 6),
            "two_or_more_leds": round(float((windows.seen >= 2).sum()) / n, 6),
            "exactly_one_led": round(float((windows.seen == 1).sum()) / n, 6)}


@dataclass(frozen=True)
class ReceiverChoice:
    """The mode a plan is made for, each planned mode's sampled coverage, and what the poses see."""

    mode: Receiver
    coverage: dict[str, float]
    seen: dict
    reason: str
    accelerometer_sigma_deg: float

    def summary(self) -> dict:
        return {"mode": self.mode.name, "coverage": {k: round(v, 6) for k, v in self.coverage.items()},
                "poses_seeing": self.seen, "reason": self.reason,
                **({"accelerometer_sigma_deg": self.accelerometer_sigma_deg} if self.mode.extra_error_terms else {})}


def _percent(share: float) -> str:
    """A share in percent, with two significant digits where one decimal would round it to 0.0."""
    return f"{100 * share:.1f} %" if share == 0 or share >= 0.0005 else f"{100 * share:.2g} %"


def check_receiver(asked: str, verify: bool) -> None:
    """:class:`UsageError` if ``asked`` (a mode other than the paper's) is not to be verified; ``auto`` unverified
    is the paper's receiver."""
    if asked != AUTO and receiver_for(asked) is not PAPER and not verify:
        raise UsageError(f"`receiver` {asked} needs verification: the two-LED receiver is judged by "
                         "verifying it; drop `verify=False`")


def choose(job: Job, asked: str, accelerometer_sigma_deg: float) -> tuple[Planned, ReceiverChoice | None]:
    """The IDs planned for the mode ``asked`` (or with ``auto`` the best mode), and the choice made (None for the
    paper's receiver asked for by name: its plans carry no receiver section)."""
    planned: dict[str, Planned] = {}
    if asked == AUTO and not job.verify:  # nothing to choose by: the paper's receiver
        asked = PAPER.name
    if asked == AUTO:
        planned[PAPER.name] = PAPER.plan(job)
        verification = planned[PAPER.name][1]
        assert verification is not None  # auto verifies
        if verification.coverage < AUTO_GOAL:
            planned.update((m.name, m.plan(job)) for m in RECEIVERS.values() if m is not PAPER)
    else:
        mode = receiver_for(asked)
        planned[mode.name] = mode.plan(job)
        if mode is PAPER:
            return planned[mode.name], None
    coverage = {k: float(v.coverage) for k, (_, v, _) in planned.items() if v is not None}
    best = max(coverage, key=lambda k: (coverage[k], RECEIVERS[k] is PAPER))
    reason = (f"asked for (--receiver {asked})" if asked != AUTO else
              f"its plan is usable: {100 * coverage[PAPER.name]:.1f} % of sampled poses decode, at least "
              f"{100 * AUTO_GOAL:.0f} %" if len(planned) == 1 else
              "no mode decodes a sampled pose; the paper's receiver is kept" if coverage[best] == 0 else
              f"decodes more sampled poses ({_percent(coverage[best])} against {_percent(min(coverage.values()))})")
    choice = ReceiverChoice(RECEIVERS[best], coverage, seen_shares(job.sample.first(job.poses_per_m2)[1]), reason,
                            accelerometer_sigma_deg)
    return planned[best], choice
