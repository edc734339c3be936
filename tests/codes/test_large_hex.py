"""The hexagonal site (1,088 luminaires 0.7 m apart, 3 m up, moved up to 3 cm): its default plan is proved, within 2 bits of the
counting bound, and unambiguous on fresh dense samples (issue 34). One site per file: workers share them."""
import pytest
from sites import check_default_plan, hexagonal_site


@pytest.mark.slow
def test_the_default_plan_is_proved_short_and_unambiguous_on_fresh_dense_samples():
    check_default_plan(hexagonal_site(), seed=41_000)
