"""The plan's seal: ``plan.yaml.seal`` beside ``plan.yaml``, a MAC under the site key (docs/plan-format.md).

``vlp-plan --key-file`` writes it with the plan; ``vlp-flash`` flashes only a plan whose seal checks, so a
``plan.yaml`` edited by someone without the site key (two luminaires given one ID, the images regenerated
by the public image builder) is refused before anything is signed. The seal is
``HMAC-SHA256(plan key, plan.yaml's UTF-8 text)`` with the plan key derived from the site key under its own
label (:func:`~planner.flash.keys.plan_key`), never a driver or journal key. It lives in a file of its own so
that ``plan.yaml`` is the same text with or without a key: its hash, written into every image, the journal and
the report, does not depend on the key.

The seal carries the time it was made (format 2, inside the MAC): the plan's *generation*. The as-built journal
records the generation of the plan it holds, and ``vlp-flash`` refuses a plan sealed before one a journal records
as flashed (:mod:`planner.flash.journal`). A format 1 seal (no time) still checks; its plan counts as older than
any sealed with a time.
"""

from __future__ import annotations

import hashlib
import hmac
import re
from datetime import UTC, datetime
from pathlib import Path

from planner._files import read_text
from planner.errors import InputError
from planner.flash.keys import plan_key

FORMAT = "vlp-plan-seal/2"
OLD_FORMAT = "vlp-plan-seal/1"
"""Seals from before generations: the plan's text alone under the MAC, no time."""
SUFFIX = ".seal"
MAX_BYTES = 1024
"""Most bytes of a seal file read (one is about 130)."""
TIME = r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\dZ"
"""A seal's time, UTC to the second (``2026-12-04T23:05:00Z``): later times compare greater as text."""
_LINES = re.compile(r"format: (?P<format>\S+)\nplan_hash: (?P<plan_hash>[0-9a-f]{16})\n"
                    rf"(?:sealed: (?P<sealed>{TIME})\n)?hmac_sha256: (?P<mac>[0-9a-f]{{64}})\n?")
_GENERATION_LABEL = b"VLP plan seal v2\x00"


def seal_path(plan_path: str | Path) -> Path:
    """Where the seal of ``plan_path`` lives: ``plan.yaml.seal`` beside ``plan.yaml``."""
    p = Path(plan_path)
    return p.with_name(p.name + SUFFIX)


def plan_mac(site_key: bytes, text: str, sealed: str = "") -> str:
    """HMAC-SHA256 under the plan key, hex, over ``"VLP plan seal v2" 0x00`` | the seal's time | 0x00 | the plan's
    UTF-8 text (format 2), or, for a format 1 seal (``sealed`` empty), over the text alone."""
    head = _GENERATION_LABEL + sealed.encode("ascii") + b"\x00" if sealed else b""
    return hmac.new(plan_key(site_key), head + text.encode("utf-8"), hashlib.sha256).hexdigest()


def _digest(text: str) -> str:
    """The plan hash (``planner.plan.model.plan_hash``, a later stage than this one)."""
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:16]


def seal_text(site_key: bytes, text: str, sealed: str | None = None) -> str:
    """The seal file of the plan whose text is ``text``, made at ``sealed`` (default: now): its format, the plan
    hash (so that a seal of another plan is told from a forged one), the time and the MAC, one ``key: value`` a
    line."""
    sealed = sealed or datetime.now(UTC).strftime("%Y-%m-%dT%H:%M:%SZ")
    return (f"format: {FORMAT}\nplan_hash: {_digest(text)}\nsealed: {sealed}\n"
            f"hmac_sha256: {plan_mac(site_key, text, sealed)}\n")


def _checked(plan_path: str | Path, text: str, site_key: bytes) -> tuple[str | None, str]:
    """(what is wrong with the seal of the plan at ``plan_path`` whose text is ``text``, or None; the seal's time,
    "" for a format 1 seal)."""
    path = seal_path(plan_path)
    if not path.exists():
        return f"not sealed (no {path.name} beside it)", ""
    try:
        found = _LINES.fullmatch(read_text(path, "plan seal", max_bytes=MAX_BYTES))
    except InputError as exc:
        return f"its seal cannot be read ({exc})", ""
    if found is None or (found["format"], bool(found["sealed"])) not in ((FORMAT, True), (OLD_FORMAT, False)):
        return f"its seal {path.name} is not a {FORMAT} file (damaged or written by hand)", ""
    if found["plan_hash"] != _digest(text):
        return (f"its seal {path.name} is of plan {found['plan_hash']}, not of this one ({_digest(text)}): the plan "
                "was edited since it was sealed, or the seal copied from another plan"), ""
    sealed = found["sealed"] or ""
    if not hmac.compare_digest(found["mac"], plan_mac(site_key, text, sealed)):
        return "its seal does not check under this site key (forged, or sealed with another site key)", ""
    return None, sealed


def seal_problem(plan_path: str | Path, text: str, site_key: bytes) -> str | None:
    """What is wrong with the seal of the plan at ``plan_path`` whose text is ``text`` (None: it checks)."""
    return _checked(plan_path, text, site_key)[0]


def check_seal(plan_path: str | Path, text: str, site_key: bytes) -> str:
    """The time the plan was sealed ("" for a format 1 seal): :class:`InputError` in one line, saying what to do,
    unless the plan's seal checks under ``site_key``."""
    problem, sealed = _checked(plan_path, text, site_key)
    if problem is not None:
        raise InputError(f"{plan_path}: {problem}; vlp-flash flashes only a plan sealed under the site key: "
                         f"{SEAL_HINT.format(plan=plan_path)}")
    return sealed


SEAL_HINT = ("make it with vlp-plan LAYOUT --key-file FILE, or, after an edit vlp-verify passes, seal it with "
             "vlp-plan --from-plan {plan} --key-file FILE")
"""What to do about a plan whose seal is missing or does not check."""
