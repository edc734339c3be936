"""Locate a photo and check what each luminaire in it plays: its planned ID, or a wrong one.

The photo's decoded LEDs are identified and located as any snapshot
(:func:`planner.positioning.locate.locate`). A luminaire flashed with the wrong ID
spoils that: no place explains its ID there. So if every LED together fits no one
place, each is left out in turn and the photo is located on the others, then each two,
up to :data:`MAX_LEFT_OUT` (always keeping three); at the fewest left out that fit, every
fit must be one place (two places and the photo is not located). The located
pose then says which luminaire of the plan each blob is (the one whose image centre
lies nearest, within :data:`~planner.twin.twin.MATCH_SHARE` of its minor axis), and its
decoded ID is compared with the plan's.

So up to :data:`MAX_LEFT_OUT` wrong luminaires are found in one photo; with more it is not
located (take another photo with fewer of them, or more right ones).
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import combinations

import numpy as np

from planner.camera.ellipse import centre_and_shape
from planner.camera.model import Camera, disc_dual_conic
from planner.defaults import MAX_RESIDUAL_PX
from planner.errors import PositioningError
from planner.photo.decode import PhotoBlob
from planner.positioning.locate import Located, Site, Snapshot, locate, refine_on_centres
from planner.twin.twin import MATCH_SHARE

SAME_PLACE_M = 0.10
"""Two fixes of one photo this close together are the same place [m]."""

MAX_LEFT_OUT = 3
"""Most LEDs left out of a photo's fix: the wrong luminaires one photo can find."""


@dataclass(frozen=True)
class PhotoFix:
    """A photo's position (None, with the reason, if not located) and the luminaire the pose puts at each blob."""

    located: Located | None
    problem: str
    luminaire: list[int | None]  # per blob: index into the site, or None
    left_out: tuple[int, ...] = ()  # the blobs left out of the fix (their IDs fit no place)
    on_centres: bool = False  # the position refitted to the ellipse centres (saturated LEDs, :func:`_fitted`)


def _snapshot(blobs: list[PhotoBlob], use: list[int], camera: Camera) -> Snapshot:
    """The blobs ``use`` as a snapshot for the ideal camera, nearest the image centre first (the paper's order)."""
    ideal = camera.ideal()
    read = [(b.id, b.ideal) for b in (blobs[k] for k in use) if b.id is not None and b.ideal is not None]
    read.sort(key=lambda r: float(np.hypot(r[1].cx - ideal.cx_px, r[1].cy - ideal.cy_px)))
    return Snapshot(ideal, [i for i, _ in read], [e for _, e in read])


def read_and_planned(blobs: list[PhotoBlob], site: Site) -> list[int]:
    """Blobs with an ideal ellipse and a decoded ID the plan uses."""
    return [k for k, b in enumerate(blobs) if b.id is not None and b.ideal is not None and np.any(site.ids == b.id)]


def locate_photo(site: Site, blobs: list[PhotoBlob], camera: Camera, method: str = "perspective",
                 max_residual_px: float = MAX_RESIDUAL_PX) -> PhotoFix:
    """Locate a photo on ``site`` from its blobs with ``method``, leaving out the fewest (up to
    :data:`MAX_LEFT_OUT`) whose IDs fit no place if need be."""
    use = read_and_planned(blobs, site)
    none: list[int | None] = [None] * len(blobs)
    if not blobs:
        return PhotoFix(None, "no LED blobs in the photo (nothing stands out from the ceiling); photograph the "
                        "luminaires, with a short exposure", none)
    if len(use) < 3:
        return PhotoFix(None, f"{len(use)} of {len(blobs)} LED blobs decoded to an ID of the plan: a position needs "
                        "three", none)
    try:
        return _matched(site, blobs, camera, *_fitted(site, blobs, use, camera, method, max_residual_px), ())
    except PositioningError as exc:
        first = str(exc)
    for count in range(1, min(MAX_LEFT_OUT, len(use) - 3) + 1):
        fits: list[tuple[tuple[int, ...], Located, bool]] = []
        for out in combinations(use, count):
            try:
                fits.append((out, *_fitted(site, blobs, [j for j in use if j not in out], camera, method,
                                           max_residual_px)))
            except PositioningError:
                continue
        if not fits:
            continue
        if any(np.linalg.norm(f[1].fix.position - g[1].fix.position) >= SAME_PLACE_M for f in fits for g in fits):
            return PhotoFix(None, f"{first} (and leaving out {count} LED(s) fits two places)", none)
        out, found, on_centres = min(fits, key=lambda f: f[1].fix.residual_px)
        return _matched(site, blobs, camera, found, on_centres, out)
    return PhotoFix(None, first, none)


def _fitted(site: Site, blobs: list[PhotoBlob], use: list[int], camera: Camera, method: str,
            max_residual_px: float) -> tuple[Located, bool]:
    """The blobs ``use`` located; with the perspective method, four or more LEDs and a saturated one among them,
    the position refitted to their centres (their sizes read large: :mod:`planner.photo.tones`), and whether it was."""
    snap = _snapshot(blobs, use, camera)
    found = locate(site, snap, method, max_residual_px)
    if method != "perspective" or not any(blobs[k].saturated for k in use):
        return found, False
    refined = refine_on_centres(site, snap, found, max_residual_px)
    return refined, refined is not found


def _matched(site: Site, blobs: list[PhotoBlob], camera: Camera, found: Located, on_centres: bool,
             left_out: tuple[int, ...]) -> PhotoFix:
    """The fix with every blob matched to the luminaire whose image the pose puts at its centre."""
    pos, rot = found.fix.position, found.fix.rotation
    centres, shapes, ok = centre_and_shape(disc_dual_conic(pos, rot, site.xyz, site.radii, camera.ideal()))
    ok &= (site.xyz - pos) @ rot[:, 2] > 0  # in front of the camera
    minor = np.linalg.eigvalsh(shapes)[:, 0]
    owner: list[int | None] = []
    for b in blobs:
        if b.ideal is None or not ok.any():
            owner.append(None)
            continue
        off = np.where(ok, np.hypot(*(centres - b.ideal.centre).T), np.inf)
        k = int(np.argmin(off))
        owner.append(k if off[k] <= MATCH_SHARE * 2 * minor[k] else None)
    return PhotoFix(found, "", owner, left_out, on_centres)


def verdict(blob: PhotoBlob, planned: int | None) -> str:
    """What a blob says of the luminaire at it: ``right``, ``wrong``, ``unread`` or ``unknown`` (no luminaire)."""
    if planned is None:
        return "unknown"
    if blob.id is None:
        return "unread"
    return "right" if blob.id == planned else "wrong"


@dataclass(frozen=True)
class Sighting:
    """One luminaire in one photo: the ID it was read playing (None: not read) and the plan's."""

    photo: str
    luminaire: int
    plays: int | None
    planned: int
    problem: str = ""  # why the ID was not read


def sightings(photo: str, site: Site, blobs: list[PhotoBlob], fix: PhotoFix) -> list[Sighting]:
    """The luminaires a located photo shows, with what each plays."""
    return [Sighting(photo, k, b.id, int(site.ids[k]), b.problem) for b, k in zip(blobs, fix.luminaire)
            if k is not None]


def luminaire_status(seen: list[Sighting]) -> dict[int, tuple[str, list[Sighting]]]:
    """Per luminaire seen: ``wrong`` if any photo read it playing another ID, else ``right`` if one read its
    planned ID, else ``unread``; with the sightings behind it."""
    out: dict[int, tuple[str, list[Sighting]]] = {}
    for k in sorted({s.luminaire for s in seen}):
        mine = [s for s in seen if s.luminaire == k]
        read = [s for s in mine if s.plays is not None]
        status = ("wrong" if any(s.plays != s.planned for s in read) else "right" if read else "unread")
        out[k] = (status, mine)
    return out


def _ellipse_document(e) -> dict | None:
    """An ellipse as the observation file writes one (docs/positioning.md), to 1/1000 px."""
    if e is None:
        return None
    return {"cx": round(e.cx, 3), "cy": round(e.cy, 3), "major": round(e.major, 3), "minor": round(e.minor, 3),
            "angle_deg": round(float(np.degrees(e.angle_rad)), 3)}


def blob_documents(site: Site, blobs: list[PhotoBlob], fix: PhotoFix | None) -> list[dict]:
    """The JSON of every blob: where it is, its stripes, its ID or the reason none, and (once located) the
    luminaire there and the verdict."""
    out = []
    for k, b in enumerate(blobs):
        lum = fix.luminaire[k] if fix is not None else None
        problem = b.problem or ("" if np.any(site.ids == b.id) else f"ID {b.id} is not in the plan")
        doc = {"bbox_px": list(b.bbox), "ellipse": _ellipse_document(b.ellipse),
               "stripe_period_rows": b.stripe_period_rows, "chips": len(b.chips), "id": b.id, "problem": problem}
        if b.tone is not None:
            doc.update(tone_hz=round(b.tone.tone_hz, 1), tone_sigma_hz=round(b.tone.sigma_hz, 1),
                       tone_probability=round(b.tone_probability, 4), rows=b.tone.rows, saturated=b.saturated)
        if fix is not None and fix.located is not None:
            planned = None if lum is None else int(site.ids[lum])
            doc.update(luminaire=None if lum is None else site.names[lum], planned_id=planned,
                       verdict=verdict(b, planned), left_out=k in fix.left_out)
        out.append(doc)
    return out


@dataclass(frozen=True)
class PhotoCheck:
    """One site photo of the as-built check: its blobs and fix, or why it was not read or located."""

    file: str
    blobs: list[PhotoBlob]
    fix: PhotoFix | None  # None: the photo could not be read
    problem: str  # "" if located


def check_photo(site: Site, file: str, blobs: list[PhotoBlob], camera: Camera) -> PhotoCheck:
    """Locate one decoded site photo for the as-built check."""
    fix = locate_photo(site, blobs, camera)
    return PhotoCheck(file, blobs, fix, fix.problem)
