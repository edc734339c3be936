"""The 32 x 32 lattice 0.5 m apart (1,024 luminaires): its default plan is proved, within 2 bits of the
counting bound, and unambiguous on fresh dense samples (issue 34). One site per file: workers share them."""
import pytest
from sites import check_default_plan, square_lattice


@pytest.mark.slow
def test_the_default_plan_is_proved_short_and_unambiguous_on_fresh_dense_samples():
    check_default_plan(square_lattice(), seed=40_000)
