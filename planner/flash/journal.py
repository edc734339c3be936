"""The as-built journal: which driver got which image, when, and what each driver reported holding.

One JSON file (format ``vlp-asbuilt/2``) per plan. Each entry written by ``vlp-flash`` carries a
``seal``, an HMAC under a key derived from the site key (:func:`~planner.flash.keys.journal_key`) over
the plan hash, the luminaire's name and the entry; the file's ``head`` lists every entry's name and seal, in
order, under one more HMAC that also covers the plan hash and the plan's generation (its seal time,
:mod:`planner.flash.seal`). ``vlp-flash``, and ``vlp-report --key-file``, refuse a journal with an entry whose
seal does not check (edited, written by hand, moved to another luminaire or plan) and one whose entries are not
the head's (an entry removed, reordered, added, or an older one put back), naming the entry; and ``vlp-flash``
refuses a plan sealed before the one the journal records as flashed. A ``vlp-asbuilt/1`` journal (entries
sealed one by one, no head) is read only without a key.
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

FORMAT = "vlp-asbuilt/2"
OLD_FORMAT = "vlp-asbuilt/1"
"""Journals before the head: read without a key (vlp-report), refused with one (a removal could not be told)."""
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


DISTRUST = ("so no entry of it is believed: move the journal away; vlp-flash --verify-only rebuilds it from the "
            "drivers' proved answers")
"""The end of every refusal of a journal's seals: what follows and what to do."""


def seal(key: bytes, plan_hash: str, name: str, entry: dict) -> str:
    """The seal of ``name``'s ``entry`` (its ``seal`` field aside): HMAC-SHA256 over canonical JSON, hex."""
    body = {k: v for k, v in entry.items() if k != "seal"}
    text = json.dumps([plan_hash, name, body], sort_keys=True, separators=(",", ":"), ensure_ascii=True)
    return hmac.new(key, text.encode("ascii"), hashlib.sha256).hexdigest()


def head_mac(key: bytes, plan_hash: str, plan_sealed: str, index: list) -> str:
    """The head's HMAC-SHA256 (hex) over the plan hash, the plan's seal time and ``index``, the [name, seal] of every
    entry in the file's order: it fixes which entries the journal holds, in which order, and which of each."""
    text = json.dumps(["vlp-asbuilt/2 head", plan_hash, plan_sealed, index], separators=(",", ":"), ensure_ascii=True)
    return hmac.new(key, text.encode("ascii"), hashlib.sha256).hexdigest()


def _index(doc: dict) -> list | None:
    """The head's [name, seal] pairs if the head is well formed, else None."""
    head = doc.get("head")
    if not isinstance(head, dict) or not isinstance(head.get("hmac_sha256"), str):
        return None
    index = head.get("entries")
    if not isinstance(index, list):
        return None
    if not all(isinstance(i, list) and len(i) == 2 and all(isinstance(s, str) for s in i) for i in index):
        return None
    return index if isinstance(doc.get("plan_sealed", ""), str) else None


class Journal:
    """The journal at ``path`` for the plan with hash ``plan_hash``, sealed at ``plan_sealed`` (its generation; ""
    for a seal without a time), read at once if it exists. With ``site_key`` every seal, and the head, is checked on
    reading and made on writing; without it (vlp-report without --key-file) it is read unchecked."""

    def __init__(self, path: str | Path, plan_hash: str, site_key: bytes | None = None, plan_sealed: str = ""):
        self.path = Path(path)
        self.plan_hash = plan_hash
        self.plan_sealed = self.recorded_sealed = plan_sealed  # the latter: the newest the file records
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
        if not isinstance(doc, dict) or doc.get("format") not in (FORMAT, OLD_FORMAT):
            raise InputError(f"{self.path}: not a {FORMAT} journal; move it away to start a new one")
        if self._key is not None and doc["format"] == OLD_FORMAT:
            raise InputError(f"{self.path}: a {OLD_FORMAT} journal, from a vlp-flash before the journal's head: an "
                             f"entry removed from it or an older one put back cannot be told, {DISTRUST}")
        if doc.get("plan_hash") != self.plan_hash:
            self._older_plan(doc)
            raise InputError(f"{self.path}: journal of plan {doc.get('plan_hash')}, not of this plan "
                             f"({self.plan_hash}); give another `journal` for a new plan")
        checked = validated(_JournalFile, doc, str(self.path), "a journal", strict=True,
                            hint="; the journal was edited or damaged: move it away to start a new one")
        if self._key is not None:
            for name, raw in doc.get("luminaires", {}).items():
                if not hmac.compare_digest(str(raw.get("seal", "")), seal(self._key, self.plan_hash, name, raw)):
                    raise InputError(f"{self.path}: journal seal does not check: the entry of {name!r} was edited "
                                     "(or written by hand, by a vlp-flash before seals, or under another site key), "
                                     + DISTRUST)
            self._check_head(doc)
        self.recorded_sealed = max(self.plan_sealed, str(doc.get("plan_sealed", "")))
        return {name: entry.model_dump(exclude_unset=True) for name, entry in checked.luminaires.items()}

    def _head_checks(self, doc: dict) -> list | None:
        """The head's index if its HMAC checks under the journal key, else None."""
        index = _index(doc)
        if index is None or self._key is None:
            return None
        mac = head_mac(self._key, str(doc.get("plan_hash")), doc.get("plan_sealed", ""), index)
        return index if hmac.compare_digest(doc["head"]["hmac_sha256"], mac) else None

    def _check_head(self, doc: dict) -> None:
        """:class:`InputError` naming the first entry that is not the head's: removed, added, an older one put back,
        or out of order (the head fixes which entries vlp-flash last wrote, and in which order)."""
        index = self._head_checks(doc)
        if index is None:
            raise InputError(f"{self.path}: journal head missing or not checking (edited, written by hand, or under "
                             f"another site key), {DISTRUST}")
        listed, found = dict(index), doc.get("luminaires", {})
        why = next((f"the entry of {n!r} was removed (the head lists it)" for n in listed if n not in found), None)
        why = why or next((f"the entry of {n!r} was added (the head does not list it: copied from another journal?)"
                           for n in found if n not in listed), None)
        why = why or next((f"the entry of {n!r} is not the one vlp-flash wrote last (an older entry of it put back, "
                           "or one from another journal of this plan)" for n in found
                           if found[n].get("seal") != listed[n]), None)
        if why is None and list(found) != [n for n, _ in index]:
            n = next(a for a, (b, _) in zip(found, index, strict=True) if a != b)
            why = f"the entries were reordered (the head lists another entry where {n!r} is)"
        if why is not None:
            raise InputError(f"{self.path}: journal chain broken: {why}, {DISTRUST}")

    def _older_plan(self, doc: dict) -> None:
        """Refuse this plan if the journal, of another plan, records that plan flashed and sealed after this one."""
        theirs = doc.get("plan_sealed", "")
        entries = doc.get("luminaires")
        flashed = isinstance(entries, dict) and any(isinstance(e, dict) and e.get("verified") is True
                                                    and e.get("status") in HOLDS_IMAGE for e in entries.values())
        if not (flashed and isinstance(theirs, str) and theirs > self.plan_sealed and self._head_checks(doc)):
            return
        raise InputError(f"{self.path}: this plan ({self.plan_hash}, sealed {self.plan_sealed or 'without a time'}) "
                         f"is older than plan {doc.get('plan_hash')} (sealed {theirs}), which this journal records as "
                         "flashed: vlp-flash does not put an older plan back; flash the newer plan, or, to put this "
                         "one back deliberately, seal it anew (vlp-plan --from-plan PLAN -o NEWDIR --key-file FILE)")

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
            doc: dict = {"format": FORMAT, "plan_hash": self.plan_hash, "plan_sealed": self.recorded_sealed,
                         "luminaires": dict(sorted(self.entries.items()))}
            if self._key is not None:
                index = [[n, e["seal"]] for n, e in doc["luminaires"].items()]
                doc["head"] = {"entries": index, "hmac_sha256": head_mac(self._key, self.plan_hash,
                                                                         self.recorded_sealed, index)}
            write_text_atomically(self.path, json.dumps(doc, indent=2) + "\n")
