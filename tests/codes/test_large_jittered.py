"""The jittered site (2,040 luminaires on a 0.6 m lattice, each moved up to 12 cm): its default plan is proved, within 2 bits of the
counting bound, and unambiguous on fresh dense samples (issue 34). One site per file: workers share them."""
import pytest
from sites import check_default_plan, jittered_site


@pytest.mark.slow
def test_the_default_plan_is_proved_short_and_unambiguous_on_fresh_dense_samples():
    check_default_plan(jittered_site(), seed=42_000)
