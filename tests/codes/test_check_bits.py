import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from planner.codes.check_bits import check_code
from planner.errors import UsageError


@pytest.mark.parametrize("alphabet,id_bits,distance,word_bits", [
    (16, 4, 1, 4), (16, 4, 2, 5), (16, 4, 3, 7),   # A(7, 3) = 16: the Hamming code
    (64, 6, 2, 7), (64, 6, 3, 10),                   # A(9, 3) = 40 < 64 <= A(10, 3) = 72
    (8, 3, 3, 6),
])
def test_word_lengths_are_the_best_known(alphabet, id_bits, distance, word_bits):
    code = check_code(alphabet, id_bits, distance)
    assert code.word_bits == word_bits and code.check_bits == word_bits - id_bits
    assert len(set(code.codewords.tolist())) == alphabet


@settings(max_examples=30, deadline=None)
@given(alphabet=st.integers(2, 80), distance=st.integers(2, 4))
def test_codewords_keep_their_distance_and_misreads_are_detected(alphabet, distance):
    bits = max(1, int(np.ceil(np.log2(alphabet))))
    code = check_code(alphabet, bits, distance)
    words = code.codewords.tolist()
    assert all(max(words) < (1 << code.word_bits) for _ in [0])
    for a, b in itertools.combinations(words, 2):
        assert bin(a ^ b).count("1") >= distance
    book = set(words)
    for w in words:  # every word with fewer than `distance` flipped bits is not a codeword
        for flips in range(1, distance):
            for pos in itertools.combinations(range(code.word_bits), flips):
                mask = sum(1 << p for p in pos)
                assert (w ^ mask) not in book


def test_distance_below_one_is_a_usage_error():
    with pytest.raises(UsageError):
        check_code(16, 4, 0)
