"""Which receiver mode serves a site: the one asked for, or with ``auto`` the paper's three-LED receiver
and, where it decodes fewer than :data:`AUTO_GOAL` of the sampled poses, the other modes too, keeping the
mode that decodes more poses (docs/schemes.md, "Receiver modes"). The modes: :mod:`planner.receivers.modes`.
"""

from __future__ import annotations

from dataclasses import dataclass

from planner.errors import UsageError
from planner.receivers.base import Job, Planned, Receiver
from planner.receivers.modes import AUTO, PAPER, RECEIVERS, receiver_for
from planner.verify.windows import PoseWindows

AUTO_GOAL = 0.9
"""``--receiver auto`` plans the gravity receiver too where the three-LED one decodes fewer poses than this."""


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


def check_receiver(asked: str, verify: bool) -> None:
    """:class:`UsageError` if ``asked`` (a mode other than the paper's, or ``auto``) is not to be verified."""
    if (asked == AUTO or receiver_for(asked) is not PAPER) and not verify:
        raise UsageError(f"--receiver {asked} needs verification: the two-LED receiver is judged by "
                         "verifying it; drop --no-verify")


def choose(job: Job, asked: str, accelerometer_sigma_deg: float) -> tuple[Planned, ReceiverChoice | None]:
    """The IDs planned for the mode ``asked`` (or with ``auto`` the best mode), and the choice made (None for the
    paper's receiver asked for by name: its plans carry no receiver section)."""
    planned: dict[str, Planned] = {}
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
              f"three-LED receiver decodes {100 * coverage[PAPER.name]:.1f} % of sampled poses, at least the goal "
              f"of {100 * AUTO_GOAL:.0f} %" if len(planned) == 1 else
              f"decodes more sampled poses ({100 * coverage[best]:.1f} % against "
              f"{100 * min(coverage.values()):.1f} %)")
    choice = ReceiverChoice(RECEIVERS[best], coverage, seen_shares(job.sample.first(job.poses_per_m2)[1]), reason,
                            accelerometer_sigma_deg)
    return planned[best], choice
