"""The frame each luminaire's driver repeats: preamble, line-coded ID word.

A frame is a string of chips ('1' LED on, '0' off) the driver plays cyclically at
the chip rate. It is the preamble, then the word the luminaire sends (``id - 1``
in ``bits`` bits, or its codeword with check bits; docs/plan-format.md) coded
most significant bit first by a DC-balanced, run-length-limited line code:

- ``manchester``: 0 -> ``01``, 1 -> ``10`` (two chips per bit, runs of 1 or 2 chips);
- ``4b6b``: IEEE 802.15.7's 4B6B table (section 10.5.1), each nibble to six chips
  with three ones, the word zero-padded on the left to whole nibbles (runs up to 4).

Each preamble is balanced and holds a run one longer than any the code makes, so
it occurs exactly once per frame period in the cyclic stream, from any phase; its
first and last chips differ from the runs next to it so frames keep the run limit
``max_run``. docs/modulation.md has the tables and the proof by enumeration that
``tests/test_frame.py`` runs.
"""

from __future__ import annotations

from dataclasses import dataclass

from planner.errors import InputError

# IEEE 802.15.7-2011 Table 118 (4B6B): nibble (MSB first) -> six chips, three of them ones.
FOUR_B_SIX_B = ("001110", "001101", "010011", "010110", "010101", "100011", "100110", "100101",
                "011001", "011010", "011100", "110001", "110010", "101001", "101010", "101100")


@dataclass(frozen=True)
class LineCode:
    """A line code: preamble, chips per payload symbol, and the longest run a frame holds."""

    name: str
    preamble: str
    max_run: int  # longest run of equal chips in any cyclic frame, preamble included

    def encode(self, word: int, bits: int) -> str:
        """Chips of ``word`` (``bits`` bits, MSB first)."""
        text = format(word, f"0{bits}b")
        if self.name == "manchester":
            return "".join("10" if b == "1" else "01" for b in text)
        text = text.zfill(-(-bits // 4) * 4)
        return "".join(FOUR_B_SIX_B[int(text[i:i + 4], 2)] for i in range(0, len(text), 4))

    def decode(self, chips: str, bits: int) -> int | None:
        """Inverse of :meth:`encode`; None if the chips are not a valid code word."""
        if self.name == "manchester":
            pairs = [chips[i:i + 2] for i in range(0, 2 * bits, 2)]
            if len(chips) != 2 * bits or any(p not in ("01", "10") for p in pairs):
                return None
            return int("".join("1" if p == "10" else "0" for p in pairs), 2)
        groups = [chips[i:i + 6] for i in range(0, len(chips), 6)]
        if len(chips) != 6 * -(-bits // 4) or any(g not in FOUR_B_SIX_B for g in groups):
            return None
        value = int("".join(format(FOUR_B_SIX_B.index(g), "04b") for g in groups), 2)
        return value if value < 2**bits else None

    def payload_chips(self, bits: int) -> int:
        return 2 * bits if self.name == "manchester" else 6 * -(-bits // 4)


LINE_CODES = {
    # runs 1-2 in the payload; the preamble's runs of 3 never occur there
    "manchester": LineCode("manchester", "01110001", 3),
    # runs up to 4 in the payload (e.g. 011100 + 001110); the preamble's runs of 5 never occur there
    "4b6b": LineCode("4b6b", "011111000001", 5),
}


def line_code(name: str) -> LineCode:
    if name not in LINE_CODES:
        raise InputError(f"unknown line code {name!r}; use one of: {', '.join(LINE_CODES)}")
    return LINE_CODES[name]


def frame_chips(word: int, bits: int, code: LineCode) -> str:
    """One frame period: the preamble, then ``word`` line-coded."""
    if not 0 <= word < 2**bits:
        raise InputError(f"word {word} does not fit in {bits} bits")
    return code.preamble + code.encode(word, bits)


def longest_run(chips: str, cyclic: bool = True) -> int:
    """Longest run of equal chips (across the wrap when ``cyclic``)."""
    if not chips:
        return 0
    text = chips + chips if cyclic else chips
    best = run = 1
    for a, b in zip(text, text[1:]):
        run = run + 1 if a == b else 1
        best = max(best, run)
    return min(best, len(chips)) if cyclic else best


def decode_stream(stream: str, bits: int, code: LineCode) -> int:
    """The word in a chip stream holding at least one whole frame, starting at any phase.

    Finds the preamble, reads the payload after it; a stream with no whole frame, or
    whose payload is not a code word, raises :class:`InputError`.
    """
    frame = len(code.preamble) + code.payload_chips(bits)
    start = stream.find(code.preamble)
    while start != -1 and start + frame <= len(stream):
        word = code.decode(stream[start + len(code.preamble):start + frame], bits)
        if word is not None:
            return word
        start = stream.find(code.preamble, start + 1)
    raise InputError(f"no whole {code.name} frame of {frame} chips in a stream of {len(stream)} chips")
