"""The hexagonal site (1,088 luminaires 0.7 m apart, 3 m up, moved up to 3 cm): its default plan is proved, within 2 bits of the
counting bound, and unambiguous on fresh dense samples (issue 34). The suite plans a smaller site of the same kind and
takes one sample; the Done-when's site and five samples run under ``--acceptance``. One site per file."""
import pytest
from sites import check_default_plan, hexagonal_site


@pytest.mark.slow
@pytest.mark.parametrize("size, samples", [pytest.param((16, 17), 1, id="272"),
                                           pytest.param((32, 34), 5, id="1088", marks=pytest.mark.acceptance)])
def test_the_default_plan_is_proved_short_and_unambiguous_on_fresh_dense_samples(size, samples):
    check_default_plan(hexagonal_site(*size), seed=41_000, samples=samples)
