"""The 32 x 32 lattice 0.5 m apart (1,024 luminaires): its default plan is proved, within 2 bits of the
counting bound, and unambiguous on fresh dense samples (issue 34). The suite plans the 16 x 16 lattice and takes one
sample; the Done-when's site and five samples run under ``--acceptance``. One site per file."""
import pytest
from sites import check_default_plan, square_lattice


@pytest.mark.slow
@pytest.mark.parametrize("n, samples", [(256, 1), pytest.param(1024, 5, marks=pytest.mark.acceptance)])
def test_the_default_plan_is_proved_short_and_unambiguous_on_fresh_dense_samples(n, samples):
    check_default_plan(square_lattice(n), seed=40_000, samples=samples)
