"""Read the light back: an LED pin's VCD trace -> chips -> the luminaire ID, and the chip rate it played.

The trace's edges fall on whole chips, so every interval between edges is a whole number of
chip periods: the chip period is measured as the span of the edges divided by the number of
chips in it (each interval rounded to whole chips at the shortest interval's scale, which holds one,
two or three chips: a frame may hold no lone chip); the
levels between edges, sampled once per measured period, are the chip stream, which the
receiver's own frame decoder (:func:`planner.modulation.frame.decode_stream`) reads.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from planner.decode.image import FrameFormat
from planner.errors import InputError
from planner.modulation.frame import decode_stream

_UNITS_S = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9, "ps": 1e-12, "fs": 1e-15}
JITTER_SHARE = 0.2
"""Largest deviation of an edge interval from a whole number of chips, as a share of one chip."""


@dataclass(frozen=True)
class LightReading:
    """What a trace says the LED played."""

    chips: str  # the chip stream read, oldest first
    chip_period_s: float
    word: int
    id: int | None  # None: the word is not a codeword of the plan

    @property
    def chip_rate_hz(self) -> float:
        return 1.0 / self.chip_period_s

    def rate_error_ppm(self, chip_rate_hz: float) -> float:
        """The measured rate's deviation from ``chip_rate_hz`` (e.g. the plan's) [ppm]."""
        return (self.chip_rate_hz - chip_rate_hz) / chip_rate_hz * 1e6


def read_vcd(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Times [s] and levels (0/1) of the first 1-bit signal's changes in a VCD file."""
    try:
        text = path.read_text(encoding="ascii", errors="replace")
    except OSError as exc:
        raise InputError(f"{path}: cannot read the trace ({exc.strerror or exc})") from None
    scale = re.search(r"\$timescale\s+(\d+)\s*(s|ms|us|ns|ps|fs)\s+\$end", text)
    var = re.search(r"\$var\s+\w+\s+1\s+(\S+)\s+\S+", text)
    if scale is None or var is None or "$enddefinitions" not in text:
        raise InputError(f"{path}: not a VCD trace with a timescale and a 1-bit signal")
    unit_s, code = int(scale[1]) * _UNITS_S[scale[2]], var[1]
    times, levels = [], []
    now = 0
    for line in text[text.index("$enddefinitions"):].splitlines()[1:]:
        if line.startswith("#") and line[1:].isdigit():
            now = int(line[1:])
        elif len(line) == len(code) + 1 and line[0] in "01" and line[1:] == code:
            times.append(now * unit_s)
            levels.append(int(line[0]))
    return np.array(times, dtype=float), np.array(levels, dtype=np.int8)


def read_light(path: Path, frame_format: FrameFormat, *, last_s: float = 0.5) -> LightReading:
    """The ID and chip rate the trace at ``path`` shows in its last ``last_s`` seconds of edges [s]."""
    times, levels = read_vcd(path)
    if len(times) < 3:
        raise InputError(f"{path}: {len(times)} edges; the LED played no chips (blank or unconfigured driver)")
    keep = times >= times[-1] - last_s
    times, levels = times[keep], levels[keep]
    intervals = np.diff(times)
    if len(intervals) < 2 or intervals.min() <= 0:
        raise InputError(f"{path}: too few edges in the last {last_s:g} s to measure a chip rate")
    shortest = intervals.min()
    refused: InputError | None = None
    for chips_in_shortest in (1, 2, 3):  # a frame may hold no lone chip (runs of 2 and 3 only)
        base = float(np.median(intervals[intervals < 1.5 * shortest])) / chips_in_shortest
        counts = np.rint(intervals / base).astype(int)
        period_s = float((times[-1] - times[0]) / counts.sum())
        off = np.abs(intervals / period_s - counts)
        if off.max() > JITTER_SHARE:
            refused = refused or InputError(
                f"{path}: an edge interval is {off.max():.2f} chips off a whole number of chips: the trace is not "
                "chips at one rate (a configuration change inside the window?)")
            continue
        chips = "".join(str(int(level)) * int(n) for level, n in zip(levels[:-1], counts))
        try:
            word = decode_stream(chips, frame_format.word_bits, frame_format.code)
        except InputError as exc:
            refused = refused or exc
            continue
        return LightReading(chips, period_s, word, frame_format.id_of(word))
    assert refused is not None
    raise refused
