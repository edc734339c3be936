"""Optional check bits: send each ID as a codeword at a minimum Hamming distance.

With distance ``d`` between any two codewords, up to ``d - 1`` misread bits give a
word that is no codeword: the receiver detects the error instead of decoding a
wrong place. Codewords are the lexicographic code (lexicode): scan words in
increasing order and keep each one at distance >= d from all kept so far. For
d = 2 this is the even-parity code (one check bit), for d = 3 the Hamming code
(16 codewords in 7 bits, A(7, 3) = 16); lexicodes are linear and as short as the
best known codes for these small sizes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import UsageError

MAX_WORD_BITS = 24


@dataclass(frozen=True)
class CheckCode:
    """IDs 1..K sent as codewords.

    Attributes
    ----------
    distance : int
        Minimum Hamming distance between codewords (1 = no check bits).
    word_bits, id_bits : int
        Bits of a codeword and of the plain ID; ``word_bits - id_bits`` check bits.
    codewords : numpy.ndarray of int, shape (K,)
        ``codewords[id - 1]`` is the word sent for ``id``.
    """

    distance: int
    word_bits: int
    id_bits: int
    codewords: np.ndarray

    @property
    def check_bits(self) -> int:
        return self.word_bits - self.id_bits


def lexicode(word_bits: int, distance: int, limit: int) -> list[int]:
    """The first ``limit`` codewords of the length-``word_bits`` lexicode of distance ``distance``."""
    words: list[int] = []
    for w in range(1 << word_bits):
        if all(bin(w ^ c).count("1") >= distance for c in words):
            words.append(w)
            if len(words) == limit:
                break
    return words


def check_code(alphabet: int, id_bits: int, distance: int) -> CheckCode:
    """The shortest lexicode with at least ``alphabet`` codewords at ``distance``."""
    if distance < 1:
        raise UsageError(f"--check-distance {distance}: must be at least 1")
    if distance == 1:
        return CheckCode(1, id_bits, id_bits, np.arange(alphabet, dtype=np.int64))
    for word_bits in range(id_bits + 1, MAX_WORD_BITS + 1):
        words = lexicode(word_bits, distance, alphabet)
        if len(words) == alphabet:
            return CheckCode(distance, word_bits, id_bits, np.array(words, dtype=np.int64))
    raise UsageError(f"--check-distance {distance}: {alphabet} IDs need more than {MAX_WORD_BITS} bits; use less")
