"""The jittered site (2,040 luminaires on a 0.6 m lattice, each moved up to 12 cm): its default plan is proved, within 2 bits of the
counting bound, and unambiguous on fresh dense samples (issue 34). The suite plans a smaller site of the same kind and
takes one sample; the Done-when's site and five samples run under ``--acceptance``. One site per file."""
import pytest
from sites import check_default_plan, jittered_site


@pytest.mark.slow
@pytest.mark.parametrize("size, samples", [pytest.param((16, 20), 1, id="320"),
                                           pytest.param((40, 51), 5, id="2040", marks=pytest.mark.acceptance)])
def test_the_default_plan_is_proved_short_and_unambiguous_on_fresh_dense_samples(size, samples):
    check_default_plan(jittered_site(*size), seed=42_000, samples=samples)
