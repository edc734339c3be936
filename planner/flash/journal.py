"""The as-built journal: which driver got which image, when, and whether it was verified.

One JSON file (format ``vlp-asbuilt/1``), rewritten atomically after every driver
(temporary file, then rename), so an interrupted batch leaves a complete journal
that ``vlp-flash --resume`` reads to skip finished drivers. The site key never
enters it.
"""

from __future__ import annotations

import json
from datetime import UTC, datetime
from pathlib import Path

from planner._files import load_json, write_text_atomically
from planner.errors import InputError
from planner.flash.flasher import FlashResult

FORMAT = "vlp-asbuilt/1"


class Journal:
    """The journal at ``path`` for the plan with hash ``plan_hash``."""

    def __init__(self, path: str | Path, plan_hash: str):
        self.path = Path(path)
        self.plan_hash = plan_hash
        self.entries: dict[str, dict] = {}
        if self.path.exists():
            try:
                doc = load_json(self.path, "journal")
            except InputError as exc:
                raise InputError(f"{exc}; move it away to start a new one") from None
            if not isinstance(doc, dict) or doc.get("format") != FORMAT:
                raise InputError(f"{self.path}: not a {FORMAT} journal; move it away to start a new one")
            if doc.get("plan_hash") != plan_hash:
                raise InputError(f"{self.path}: journal of plan {doc.get('plan_hash')}, not of this plan ({plan_hash}); "
                                 "give another --journal for a new plan")
            entries = doc.get("luminaires", {})
            if not isinstance(entries, dict) or not all(isinstance(k, str) and isinstance(v, dict)
                                                        for k, v in entries.items()):
                raise InputError(f"{self.path}: luminaires must map each name to its record; the journal was "
                                 "edited or damaged: move it away to start a new one")
            self.entries = dict(entries)

    def done(self, name: str, image_sha256: str) -> bool:
        """True if ``name`` was flashed with this image and verified."""
        e = self.entries.get(name)
        return bool(e and e.get("verified") and e.get("image_sha256") == image_sha256)

    def record(self, name: str, luminaire_id: int, where: str, result: FlashResult) -> None:
        self.entries[name] = {
            "id": luminaire_id, "where": where, "driver_serial": result.serial, "status": result.status,
            "verified": result.verified, "image_sha256": result.image_sha256,
            "active_version": result.active_version, "message": result.message,
            "time": datetime.now(UTC).isoformat(timespec="seconds"),
        }
        self.save()

    def save(self) -> None:
        doc = {"format": FORMAT, "plan_hash": self.plan_hash, "luminaires": dict(sorted(self.entries.items()))}
        write_text_atomically(self.path, json.dumps(doc, indent=2) + "\n")
