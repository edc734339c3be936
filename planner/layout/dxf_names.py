"""What a DXF layer or block name says it is: a ceiling luminaire, another device, or nothing.

Names are split into words (``E-LITE-SWCH`` -> ``E LITE SWCH``, ``DownLight2`` -> ``DOWN
LIGHT 2``) and matched as whole words, never as substrings: ``COLUMN`` holds no ``LUM``,
``A-FLOR-TILED`` no ``LED``, ``SATELLITE`` no ``LITE``. The phrase before a word such as
``BY``, ``WITH`` or ``FOR`` is the name's head (``LIGHT POINT CONTROLLED BY TWO WAY
SWITCH`` is a light point), and the last device word of the head decides (``LIGHTING
SWITCH`` is a switch, ``SWITCHED LIGHTING`` lighting). A light qualified by ``WALL``,
``EXIT``, ``FLOOR``... is not a ceiling luminaire. :class:`Selector` turns this, or the
user's ``--layer``/``--block`` patterns, into the reader's decision for each entity.
"""

from __future__ import annotations

import fnmatch
import re
from dataclasses import dataclass
from functools import lru_cache

from planner.errors import UsageError

__all__ = ["ANNOTATION_MARKS", "BUILDING_WORDS", "LUMINAIRE", "NEUTRAL", "PRESETS", "Selector", "layer_class", "name_class",
           "selector", "words"]

LUMINAIRE = "luminaire"
NEUTRAL = ""

LIGHT_WORDS = frozenset({
    "LUM", "LUMS", "LUMINAIRE", "LUMINAIRES", "LUMINARIA", "LUMINARIAS", "LEUCHTE", "LEUCHTEN",
    "LIGHT", "LIGHTS", "LIGHTING", "LITE", "LITES", "LAMP", "LAMPS", "LED", "LEDS", "LIGHTPOINT",
    "DOWNLIGHT", "DOWNLIGHTS", "SPOTLIGHT", "SPOTLIGHTS", "TROFFER", "TROFFERS", "PENDANT", "PENDANTS",
    "HIGHBAY", "BATTEN", "BATTENS", "TUBELIGHT", "FLUORESCENT", "CFL",
})
"""Words that name a luminaire."""

OTHER_WORDS: dict[str, frozenset[str]] = {
    "switch": frozenset({"SWITCH", "SWITCHES", "SWCH", "SW", "DIMMER", "DIMMERS", "SWITCHBOARD"}),
    "fan": frozenset({"FAN", "FANS", "CEILINGFAN", "EXHAUST"}),
    "socket": frozenset({"SOCKET", "SOCKETS", "OUTLET", "OUTLETS", "RECEPTACLE", "RECEPTACLES", "RECEP", "RECPT",
                         "PLUG", "PLUGS", "POWER", "POWERPOINT"}),
    "sensor": frozenset({"SENSOR", "SENSORS", "DETECTOR", "DETECTORS", "PIR", "OCCUPANCY", "MOTION", "SMOKE",
                         "THERMOSTAT"}),
    "exit sign": frozenset({"EXIT", "SIGN", "SIGNS", "SIGNAGE"}),
    "wall light": frozenset({"SCONCE", "SCONCES", "WALLLIGHT", "WALLPACK"}),
    "annotation": frozenset({"TEXT", "NOTE", "NOTES", "DIMS", "ANNO", "IDEN", "TAG", "TAGS", "CIRC", "CIRCUIT",
                             "CIRCUITS", "WIRE", "WIRING", "CONDUIT", "LEGEND", "TITLE", "ANNOTATION", "ANNOTATIONS",
                             "ARROW", "ARROWS", "LEADER", "LEADERS", "LABEL", "LABELS", "KEYNOTE", "CALLOUT",
                             "DIMENSION", "DIMENSIONS"}),
    "other device": frozenset({"SPEAKER", "SPEAKERS", "CCTV", "DATA", "TEL", "TELEPHONE", "TV", "BELL", "DOORBELL"}),
}
"""Words that name something other than a luminaire, by what it is."""

_OTHER = {word: what for what, group in OTHER_WORDS.items() for word in group}

ANNOTATION_MARKS = frozenset({"TEXT", "NOTE", "NOTES", "DIMS", "ANNO", "IDEN", "TAG", "TAGS", "LEGEND", "TITLE",
                              "ANNOTATION", "ANNOTATIONS", "ARROW", "ARROWS", "LEADER", "LEADERS", "LABEL", "LABELS",
                              "KEYNOTE", "CALLOUT", "DIMENSION", "DIMENSIONS"})
"""Annotation words that make a name an annotation wherever they stand in its head: ``TAG-LED-ARROW`` is
a tag pointing at a light, not a light (the wiring words ``CIRCUIT``, ``WIRE``... decide only as the last)."""

BUILDING_WORDS = frozenset({"COLUMN", "COLUMNS", "COL", "COLS", "PILLAR", "PILLARS", "PIER", "PIERS", "BEAM", "BEAMS",
                            "DOOR", "DOORS", "WINDOW", "WINDOWS", "STAIR", "STAIRS", "FURNITURE", "DESK", "DESKS",
                            "TABLE", "TABLES", "CHAIR", "CHAIRS"})
"""Words that name a building element or furniture: a block so named is no luminaire even on a lighting
layer (the name itself stays neutral: a ``COLUMN`` elsewhere is neither taken nor rejected)."""

QUALIFIERS: dict[str, frozenset[str]] = {
    "wall light": frozenset({"WALL", "BRACKET", "SCONCE"}),
    "exit sign": frozenset({"EXIT", "SIGN"}),
    "floor or table lamp": frozenset({"FLOOR", "TABLE", "DESK", "STANDING", "READING"}),
    "outdoor light": frozenset({"BOLLARD", "GARDEN", "STREET", "OUTDOOR", "FACADE"}),
}
"""Words that make a light something other than a ceiling luminaire when they stand before it in the head."""

NOT_LIGHTS = frozenset({"SKYLIGHT", "SKYLIGHTS", "DAYLIGHT", "DAYLIGHTING", "HIGHLIGHT", "HIGHLIGHTS", "TWILIGHT",
                        "SUNLIGHT", "MOONLIGHT", "STARLIGHT", "LIGHTNING", "LIGHTWEIGHT", "LIGHTWELL", "LIGHTER"})
"""Words that hold LIGHT but name no luminaire (a skylight is a window)."""

_LED_COMPOUNDS = frozenset({"PANEL", "PANELS", "STRIP", "STRIPS", "TUBE", "TUBES", "LIGHT", "LIGHTS", "LAMP",
                            "DOWNLIGHT", "BATTEN", "SPOT", "SPOTS", "FIXTURE"})
_DEVICE_SUFFIXES = ("SWITCH", "FAN", "SOCKET", "SENSOR", "DETECTOR", "OUTLET")


def _word_class(word: str) -> str | None:
    """LUMINAIRE, a device class, or None for one word; compounds written as one word count
    (``CEILINGLIGHT``, ``LIGHTFIXTURE``, ``LEDPANEL``, ``LIGHTSWITCH``, ``EXHAUSTFAN``)."""
    if word in LIGHT_WORDS:
        return LUMINAIRE
    if word in _OTHER:
        return _OTHER[word]
    if word in NOT_LIGHTS or len(word) < 6:
        return None
    device = next((d for d in _DEVICE_SUFFIXES if word.endswith(d)), None)
    if device is not None:
        return _OTHER[device]
    if word.endswith(("LIGHT", "LIGHTS")) or word.startswith(("LIGHT", "LUMINAIRE")):
        return LUMINAIRE
    if word.startswith("LED") and word[3:] in _LED_COMPOUNDS:
        return LUMINAIRE
    return None


_HEAD_ENDS = frozenset({"BY", "WITH", "W", "VIA", "FOR", "FROM", "CONTROLLED", "CONTROL", "OPERATED", "TO", "ON",
                        "AT", "IN"})
"""Words after which a name only qualifies its head (``... CONTROLLED BY SWITCH``)."""


def words(name: str) -> list[str]:
    """The words of a name, upper case: split at non-alphanumerics, camelCase and letter/digit changes."""
    spaced = re.sub(r"(?<=[a-z])(?=[A-Z])", " ", name)
    return re.findall(r"[A-Z]+|[0-9]+", spaced.upper())


@lru_cache(maxsize=8192)  # a drawing repeats a few hundred names over many thousands of entities
def name_class(name: str) -> tuple[str, str]:
    """What a name says: ``(LUMINAIRE, word)``, ``(NEUTRAL, "")`` or ``(what, word)`` for another device
    (``"switch"``, ``"fan"``, ``"wall light"``...), with the word that decided."""
    head: list[str] = []
    for word in words(name):
        if word in _HEAD_ENDS and head:
            break
        head.append(word)
    mark = next((w for w in head if w in ANNOTATION_MARKS), None)
    if mark is not None:
        return "annotation", mark
    last = next((k for k in range(len(head) - 1, -1, -1) if _word_class(head[k]) is not None), None)
    if last is None:
        return NEUTRAL, ""
    word = head[last]
    what = _word_class(word)
    if what != LUMINAIRE:
        return str(what), word
    for what, qualifiers in QUALIFIERS.items():
        near = head[:last] if what in ("wall light", "exit sign") else head[max(0, last - 1):last]
        hit = next((w for w in near if w in qualifiers), None)
        if hit:
            return what, f"{hit} {word}"
    return LUMINAIRE, word


def layer_class(layer: str) -> tuple[str, str]:
    """What a layer name says (:func:`name_class`), where ``DIM`` in a name that says nothing else marks
    annotation: on a layer it names dimensions (``A-DIM``); in a block name, or beside a light word
    (``E-LITE-DIM``), it may mean dimmable."""
    what, word = name_class(layer)
    if what == NEUTRAL and "DIM" in words(layer):
        return "annotation", "DIM"
    return what, word


@dataclass(frozen=True)
class Preset:
    """Which layer and block names hold luminaires: names whose class is luminaire and whose words start
    with ``layer_prefix``; block names only when ``blocks``."""

    layer_prefix: tuple[str, ...]
    blocks: bool
    description: str

    def layer(self, name: str) -> bool:
        return words(name)[: len(self.layer_prefix)] == list(self.layer_prefix) and name_class(name)[0] == LUMINAIRE


PRESETS = {
    "dialux": Preset(("DLX",), False, "layers DLX_..._LUM"),
    "revit": Preset(("E", "LITE"), False, "layers E-LITE, E-LITE-..."),
    "generic": Preset((), True, "layers and blocks named by a light word"),
}
"""Preset name -> its rule; ``auto`` is their union (which is ``generic``'s)."""


def _match(name: str, patterns: tuple[str, ...]) -> bool:
    upper = name.upper()
    return any(fnmatch.fnmatchcase(upper, p.upper()) for p in patterns)


@dataclass(frozen=True)
class Selector:
    """The reader's decision for each entity: a luminaire, rejected (and why), or neither.

    With ``patterns`` (the user's ``--layer``/``--block``), those decide: a block matching a
    ``--block`` pattern is a luminaire; otherwise a block whose name says another device is
    rejected, and an entity on a layer matching ``--layer`` is a luminaire. Without them,
    the presets decide, and every name that says another device is rejected.
    """

    presets: tuple[Preset, ...]
    layers: tuple[str, ...]
    blocks: tuple[str, ...]
    label: str

    @property
    def patterns(self) -> bool:
        return bool(self.layers or self.blocks)

    def _layer_is_light(self, layer: str) -> bool:
        if self.patterns:
            return _match(layer, self.layers)
        return any(p.layer(layer) for p in self.presets)

    def insert(self, layer: str, block: str) -> tuple[str, str]:
        """``("take", why)``, ``("reject", why)`` or ``("enter", "")`` for an INSERT of ``block`` on ``layer``."""
        if self.patterns and _match(block, self.blocks):
            return "take", "block matches --block"
        what, word = name_class(block)
        if what not in (LUMINAIRE, NEUTRAL):
            return "reject", f"block name says {what} ({word})"
        layer_what, layer_word = layer_class(layer)
        if not self.patterns and layer_what == "annotation":
            return "reject", f"layer says annotation ({layer_word})"  # a tag or arrow, however it is named
        if what == LUMINAIRE and not self.patterns and any(p.blocks for p in self.presets):
            return "take", f"block name says luminaire ({word})"
        if self._layer_is_light(layer):
            building = next((w for w in words(block) if w in BUILDING_WORDS), None)
            if building is not None and not self.patterns:  # a column drawn on the lighting layer
                return "reject", f"block name says building element ({building})"
            return "take", "layer matches --layer" if self.patterns else f"layer says luminaire ({name_class(layer)[1]})"
        if not self.patterns and layer_what not in (LUMINAIRE, NEUTRAL):
            return "reject", f"layer says {layer_what} ({layer_word})"
        return "enter", ""

    def entity(self, layer: str) -> tuple[str, str]:
        """``("take", why)``, ``("reject", why)`` or ``("skip", "")`` for a CIRCLE or POINT on ``layer``."""
        if self._layer_is_light(layer):
            return "take", "layer matches --layer" if self.patterns else f"layer says luminaire ({name_class(layer)[1]})"
        what, word = layer_class(layer)
        if not self.patterns and what not in (LUMINAIRE, NEUTRAL):
            return "reject", f"layer says {what} ({word})"
        return "skip", ""


def selector(preset: str, layers: list[str] | None, blocks: list[str] | None) -> Selector:
    """The selector for ``--preset`` and the ``--layer``/``--block`` patterns (which replace the preset)."""
    key = preset.lower()
    if key == "auto":
        chosen = tuple(PRESETS.values())
    elif key in PRESETS:
        chosen = (PRESETS[key],)
    else:
        raise UsageError(f"--preset {preset!r} is unknown; use one of auto, {', '.join(PRESETS)}")
    if not layers and not blocks:  # None or [] alike: use the preset
        return Selector(chosen, (), (), f"preset {key}")
    given = [f"--layer {p!r}" for p in layers or ()] + [f"--block {p!r}" for p in blocks or ()]
    return Selector(chosen, tuple(layers or ()), tuple(blocks or ()), ", ".join(given))
