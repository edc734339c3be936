"""Reading the light back from a VCD trace (planner/flash/avr/trace.py), on traces written here."""

import numpy as np

from planner.decode.image import FrameFormat
from planner.flash.avr.trace import read_light
from planner.modulation.frame import LINE_CODES


def _vcd(path, chips: str, rate_hz: float, repeats: int) -> None:
    """A VCD of ``chips`` played ``repeats`` times at ``rate_hz``, one edge per change of level (1 ns steps)."""
    stream = chips * repeats
    lines = ["$timescale 1 ns $end", "$var wire 1 ! led $end", "$enddefinitions $end"]
    level = None
    for k, chip in enumerate(stream):
        if chip != level:
            lines += [f"#{round(k * 1e9 / rate_hz)}", f"{chip}!"]
            level = chip
    lines += [f"#{round(len(stream) * 1e9 / rate_hz)}", f"{1 - int(level)}!"]
    path.write_text("\n".join(lines) + "\n")


def test_a_frame_without_a_lone_chip_is_read_at_its_rate(tmp_path):
    """A 3-bit Manchester frame whose runs are all two or three chips long ('01110001100110' repeated): the
    shortest edge interval is two chips, so it is read at half that scale, not as a frame at half the rate."""
    frame = "01110001100110"
    trace = tmp_path / "led.vcd"
    _vcd(trace, frame, 11_000.0, 200)
    fmt = FrameFormat(LINE_CODES["manchester"], 3, 11_000.0)
    reading = read_light(trace, fmt, last_s=0.2)
    assert reading.chips in frame * (len(reading.chips) // len(frame) + 2)
    assert abs(reading.chip_rate_hz - 11_000.0) < 0.1
    assert (reading.word, reading.id) == (5, 6) and np.isclose(reading.rate_error_ppm(11_000.0), 0.0, atol=5.0)
