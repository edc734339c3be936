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

from planner.errors import UsageError

MAX_WORD_BITS = 24
MAX_DISTANCE = 8


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
    """The first ``limit`` codewords of the length-``word_bits`` lexicode of distance ``distance``.

    Candidates are screened in blocks against the words kept so far (vectorised);
    the few survivors of a block are then taken in order, as the greedy rule says.
    """
    words = np.empty(0, dtype=np.uint32)
    block = 4096
    for start in range(0, 1 << word_bits, block):
        cand = np.arange(start, min(start + block, 1 << word_bits), dtype=np.uint32)
        if len(words):
            far = (np.bitwise_count(cand[:, None] ^ words[None, :]) >= distance).all(axis=1)
            cand = cand[far]
        kept: list[int] = []
        for w in cand.tolist():
            if all(bin(w ^ c).count("1") >= distance for c in kept):
                kept.append(w)
                if len(words) + len(kept) == limit:
                    return words.tolist() + kept
        words = np.concatenate([words, np.array(kept, dtype=np.uint32)])
    return words.tolist()


def check_code(alphabet: int, id_bits: int, distance: int) -> CheckCode:
    """The shortest lexicode with at least ``alphabet`` codewords at ``distance``."""
    if not 1 <= distance <= MAX_DISTANCE:
        raise UsageError(f"`check_distance` {distance}: must be from 1 to {MAX_DISTANCE}")
    if distance == 1:
        return CheckCode(1, id_bits, id_bits, np.arange(alphabet, dtype=np.int64))
    for word_bits in range(id_bits + 1, MAX_WORD_BITS + 1):
        words = lexicode(word_bits, distance, alphabet)
        if len(words) == alphabet:
            return CheckCode(distance, word_bits, id_bits, np.array(words, dtype=np.int64))
    raise UsageError(f"`check_distance` {distance}: {alphabet} IDs need more than {MAX_WORD_BITS} bits; use less")
