"""An existing tone site audited (docs/tones.md): the layout's tones kept as its IDs, verified like any plan,
and the pairs of luminaires whose tones the camera cannot tell apart found where they share a window.

The stage runner (:mod:`planner.plan.pipeline`) calls :func:`keep_tones` in place of the code design; the error
map and the site advice follow as for a frame site, and no frames are made.
"""

from __future__ import annotations

import numpy as np

from planner.advice.tones import ToneAudit, audit_tones
from planner.errors import PlanningError, UsageError
from planner.layout.model import Layout
from planner.modulation.tones import assign_tones, check_tone_limits
from planner.receivers.base import Job, Planned, Receiver
from planner.receivers.choice import ReceiverChoice, seen_shares
from planner.receivers.modes import AUTO, PAPER, receiver_for


def check_tone_options(where: str, scheme: str, verify: bool) -> None:
    """:class:`UsageError` for the options a tone site has no use for: a scheme (its tones are kept) and no
    verification (the audit is the verification)."""
    if scheme != "auto":
        raise UsageError(f"`scheme` {scheme}: {where} is a tone site (every luminaire carries tone_hz), whose tones "
                         "are kept, not planned; drop the scheme")
    if not verify:
        raise UsageError(f"{where} is a tone site: it is audited by verifying it; drop `verify=False`")


def keep_tones(layout: Layout, tones_hz: np.ndarray, job: Job, receiver: str, accelerometer_sigma_deg: float,
               driver_max_hz: float) -> tuple[Planned, ReceiverChoice | None, ToneAudit]:
    """The tone site's IDs (tone classes), their verification for the receiver mode asked for (``auto``: the
    paper's three-LED receiver), the receiver choice (None for the paper's) and the tone audit."""
    check_tone_options(layout.source_path, job.scheme, job.verify)
    mode: Receiver = PAPER if receiver == AUTO else receiver_for(receiver)
    cam, xyz, radii = job.camera, job.xyz, job.radii
    check_tone_limits([lum.name for lum in layout.luminaires], tones_hz, cam.row_time_s, driver_max_hz,
                      layout.source_path or "layout")
    rows = mode.smallest_image_rows(xyz, radii, cam, job.sample)
    if rows is None:
        raise PlanningError(f"{layout.source_path}: no sampled camera pose sees {mode.window_words}, so there is no "
                            "LED image to judge the tones on; check the luminaire spacing against the camera "
                            "(docs/camera.md)")
    assignment = assign_tones(tones_hz, rows, job.graph)
    verification = mode.verify(xyz, radii, assignment.ids, job.outline, cam, per_m2=job.poses_per_m2, seed=job.seed,
                               tolerance_m=job.tolerance_m, install_tolerance_m=job.install_tolerance_m, recorded={},
                               runner=job.runner)
    poses, _ = job.sample.first(job.poses_per_m2)
    leds, seen = mode.window_leds(poses, xyz, radii, cam)
    audit = audit_tones(tones_hz, assignment.ids, rows, cam.row_time_s, driver_max_hz, leds, seen, poses.position)
    considered = {"tones": {"bits": assignment.bits, "ambiguous_poses": verification.count(1),
                            "window_set_conflicts": (len(verification.window_set.conflicts)
                                                     if verification.window_set else None)}}
    choice = None if mode is PAPER else ReceiverChoice(
        mode, {mode.name: float(verification.coverage)}, seen_shares(job.sample.first(job.poses_per_m2)[1]),
        f"asked for (--receiver {mode.name})", accelerometer_sigma_deg)
    return (assignment, verification, considered), choice, audit
