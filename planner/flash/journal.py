"""The as-built journal: which driver got which image, when, and what each driver reported holding.

One JSON file (format ``vlp-asbuilt/1``) per plan. Each entry written by ``vlp-flash`` carries a
``seal``, an HMAC under a key derived from the site key (:func:`~planner.flash.keys.journal_key`) over
the plan hash, the luminaire's name and the entry: ``vlp-flash``, and ``vlp-report --key-file``, refuse a
journal with an entry whose seal does not check (edited, written by hand, moved to another luminaire or plan).
After every driver the entry is merged into the file under a lock (``fcntl.flock`` on ``.<name>.lock`` beside it:
re-read, update that one luminaire, replace atomically), so two ``vlp-flash`` runs
on one plan both end with every entry, and an interrupted batch leaves a complete
journal that ``vlp-flash --resume`` reads to skip finished drivers. No key enters it.
"""

from __future__ import annotations

import fcntl
import hashlib
import hmac
import json
import os
from collections.abc import Iterator
from contextlib import contextmanager
from datetime import UTC, datetime
from pathlib import Path
from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, Strict

from planner._files import load_json, write_text_atomically
from planner._schema import Count, Text, validated
from planner.errors import InputError, UsageError
from planner.flash.flasher import FlashResult
from planner.flash.keys import journal_key

FORMAT = "vlp-asbuilt/1"
MAX_BYTES = 64 << 20
"""Most bytes of a journal read (65,534 luminaires at about 700 bytes each fit)."""
HOLDS_IMAGE = ("flashed", "current", "verified")
"""Statuses meaning the driver runs this plan's image (with ``verified`` true)."""


class _Proof(BaseModel):
    model_config = ConfigDict(extra="allow", frozen=True)

    driver_serial: Text
    image_version: Count = 0


class _Entry(BaseModel):
    """One luminaire's record; fields older journals lack take their defaults, unknown ones are kept."""

    model_config = ConfigDict(extra="allow", frozen=True)

    id: Annotated[Count, Field(ge=1)]
    where: Text = ""
    driver_serial: Text = ""
    status: Literal["flashed", "current", "verified", "failed", "unauthenticated"]
    verified: Annotated[bool, Strict()] = False
    image_sha256: Text = ""
    image_version: Count = 0
    active_version: Count = 0
    active_sha256: Text = ""
    message: Text = ""
    time: Text = ""
    last_verified: _Proof | None = None
    bound_serial: Text = ""
    replaced_drivers: list[Text] = []
    seal: Text = ""


class _JournalFile(BaseModel):
    model_config = ConfigDict(extra="allow", frozen=True)

    luminaires: dict[str, _Entry] = {}


def seal(key: bytes, plan_hash: str, name: str, entry: dict) -> str:
    """The seal of ``name``'s ``entry`` (its ``seal`` field aside): HMAC-SHA256 over canonical JSON, hex."""
    body = {k: v for k, v in entry.items() if k != "seal"}
    text = json.dumps([plan_hash, name, body], sort_keys=True, separators=(",", ":"), ensure_ascii=True)
    return hmac.new(key, text.encode("ascii"), hashlib.sha256).hexdigest()


class Journal:
    """The journal at ``path`` for the plan with hash ``plan_hash`` (read at once if it exists). With ``site_key``
    every entry's seal is checked on reading and made on writing; without it (vlp-report without --key-file) it is
    read unchecked."""

    def __init__(self, path: str | Path, plan_hash: str, site_key: bytes | None = None):
        self.path = Path(path)
        self.plan_hash = plan_hash
        self._key = journal_key(site_key) if site_key is not None else None
        self.lock_path = self.path.with_name(f".{self.path.name}.lock")
        self.entries = self._read()

    def _read(self) -> dict[str, dict]:
        if self.path.is_dir():
            raise UsageError(f"`journal` {self.path}: is a folder; give a file name such as as-built.json")
        if not self.path.exists():
            return {}
        try:
            doc = load_json(self.path, "journal", max_bytes=MAX_BYTES)
        except InputError as exc:
            raise InputError(f"{exc}; move it away to start a new one") from None
        if not isinstance(doc, dict) or doc.get("format") != FORMAT:
            raise InputError(f"{self.path}: not a {FORMAT} journal; move it away to start a new one")
        if doc.get("plan_hash") != self.plan_hash:
            raise InputError(f"{self.path}: journal of plan {doc.get('plan_hash')}, not of this plan "
                             f"({self.plan_hash}); give another `journal` for a new plan")
        checked = validated(_JournalFile, doc, str(self.path), "a journal", strict=True,
                            hint="; the journal was edited or damaged: move it away to start a new one")
        if self._key is not None:
            for name, raw in doc.get("luminaires", {}).items():
                if not hmac.compare_digest(str(raw.get("seal", "")), seal(self._key, self.plan_hash, name, raw)):
                    raise InputError(f"{self.path}: journal seal does not check: the entry of {name!r} was edited "
                                     "(or written by hand, by a vlp-flash before seals, or under another site key), so "
                                     "no entry of it is believed: move the journal away; vlp-flash --verify-only "
                                     "rebuilds it from the drivers' proved answers")
        return {name: entry.model_dump(exclude_unset=True) for name, entry in checked.luminaires.items()}

    def check_writable(self) -> None:
        """Refuse (before anything is flashed) a journal that could not be written: a missing or read-only folder."""
        with self._locked():
            if not os.access(self.path.parent, os.W_OK | os.X_OK):
                raise UsageError(f"`journal` {self.path}: the folder is not writable; choose another `journal`")

    @contextmanager
    def _locked(self) -> Iterator[None]:
        try:
            fd = os.open(self.lock_path, os.O_RDWR | os.O_CREAT, 0o666)
        except OSError as exc:
            raise UsageError(f"`journal` {self.path}: cannot write there ({exc.strerror}); choose a folder that "
                             "exists and is writable") from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX)  # released when the file is closed
            yield
        finally:
            os.close(fd)

    def verified(self, name: str, image_version: int | None = None) -> dict | None:
        """The entry of ``name`` if it records this plan's image verified (at ``image_version``, if given)."""
        e = self.entries.get(name)
        if not (e and e.get("verified") and e.get("status") in HOLDS_IMAGE):
            return None
        return e if image_version is None or self.version(e) == image_version else None

    @staticmethod
    def version(entry: dict) -> int:
        """The image version an entry records (journals before image_version had active_version only)."""
        value = entry.get("image_version", entry.get("active_version"))
        return value if isinstance(value, int) else 0

    def last_verified(self, name: str) -> tuple[str, int] | None:
        """(driver serial, image version) of the last time this plan's image was verified on ``name``'s driver,
        kept through later failures: a newer image found there since is not this plan's to replace."""
        e = self.entries.get(name) or {}
        proof = e.get("last_verified") if not self.verified(name) else e
        if not isinstance(proof, dict) or not isinstance(proof.get("driver_serial"), str):
            return None
        return proof["driver_serial"], self.version(proof)

    def bound(self, name: str) -> str:
        """The serial of the driver bound to ``name``: the one that took its first image ("" if none yet). A journal
        from before bindings binds the driver this plan's image was last verified on."""
        e = self.entries.get(name) or {}
        if e.get("bound_serial"):
            return e["bound_serial"]
        proof = self.last_verified(name)
        return proof[0] if proof else ""

    def owner(self, serial: str) -> str:
        """The luminaire ``serial`` is bound to ("" if none)."""
        return next((name for name in sorted(self.entries) if self.bound(name) == serial), "")

    def refusal(self, name: str, serial: str) -> str | None:
        """Why the proved driver ``serial`` may not take ``name``'s image (None: it may): ``name`` is bound to
        another driver, or ``serial`` to another luminaire. ``--replace-driver`` overrides, journaled."""
        bound, owner = self.bound(name), self.owner(serial)
        if bound and bound != serial:
            return (f"driver {serial} answered, but {name} is bound to driver {bound} (it took its first image; "
                    f"journal): plug {bound}, or give --replace-driver if {bound} was replaced by {serial}")
        if owner and owner != name:
            return (f"driver {serial} is bound to luminaire {owner} (journal), not {name}: plug {name}'s own driver "
                    f"(check the bus map), or give --replace-driver to move {serial} to {name}")
        return None

    def record(self, name: str, luminaire_id: int, where: str, result: FlashResult) -> None:
        """Merge ``name``'s entry into the file on disk, under the lock (other runs' entries are kept). A verified
        driver binds ``name`` to its serial if none is bound; one taking another's place (it could only pass
        :meth:`refusal` with ``--replace-driver``) is bound instead, the old serial kept in ``replaced_drivers``
        and its binding to another luminaire removed."""
        entry = {
            "id": luminaire_id, "where": where, "driver_serial": result.serial, "status": result.status,
            "verified": result.verified, "image_sha256": result.image_sha256, "image_version": result.image_version,
            "active_version": result.active_version, "active_sha256": result.active_sha256,
            "message": result.message, "time": datetime.now(UTC).isoformat(timespec="seconds"),
        }
        with self._locked():
            self.entries = self._read()
            if result.verified:
                entry["last_verified"] = {"driver_serial": result.serial, "image_version": result.image_version}
            elif (proof := self.last_verified(name)) is not None:
                entry["last_verified"] = {"driver_serial": proof[0], "image_version": proof[1]}
            old = self.entries.get(name) or {}
            bound, replaced = self.bound(name), list(old.get("replaced_drivers", []))
            changed = {name}
            if result.verified and result.serial and bound != result.serial:
                if bound:
                    replaced.append(bound)
                for other in [n for n in self.entries if n != name and self.bound(n) == result.serial]:
                    moved = {**self.entries[other], "bound_serial": "", "status": "failed", "verified": False,
                             "message": f"its driver {result.serial} was moved to {name} (--replace-driver)",
                             "replaced_drivers": [*self.entries[other].get("replaced_drivers", []), result.serial]}
                    moved.pop("last_verified", None)  # that proof was of the driver now moved away
                    self.entries[other] = moved
                    changed.add(other)
                bound = result.serial
            entry.update(bound_serial=bound, replaced_drivers=replaced)
            self.entries[name] = entry
            if self._key is not None:
                for n in changed:
                    self.entries[n]["seal"] = seal(self._key, self.plan_hash, n, self.entries[n])
            doc = {"format": FORMAT, "plan_hash": self.plan_hash, "luminaires": dict(sorted(self.entries.items()))}
            write_text_atomically(self.path, json.dumps(doc, indent=2) + "\n")
