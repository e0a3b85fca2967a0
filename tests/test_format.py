"""Values shown to people are rounded to their uncertainty, a row on one scale."""

import pytest

from pmdc_bayes._format import row_format


@pytest.mark.parametrize("value, sd, shown, shown_sd, suffix", [
    (0.0619991, 3.2e-6, "61.9991", "0.0032", "×1e-3 "),
    (1.99507, 0.0575, "1.995", "0.058", ""),
    (1.99311e-05, 7.17e-08, "19.931", "0.072", "×1e-6 "),
    (7.27e-5, 7.61e-4, "70", "760", "×1e-6 "),      # an sd larger than the value
    (12345.6, 78.0, "12.346", "0.078", "×1e3 "),
    (-3.2e-3, 1e-4, "-3.20", "0.10", "×1e-3 "),
])
def test_a_value_keeps_the_digits_its_sd_supports(value, sd, shown, shown_sd, suffix):
    f = row_format(value, sd)
    assert (f.value(value), f.sd(sd), f.suffix) == (shown, shown_sd, suffix)


def test_a_row_shares_the_estimate_s_scale_and_decimals():
    f = row_format(0.0619991, 3.2e-6)
    assert f.value(0.0620199) == "62.0199"  # the closed form beside it, same scale
    assert f.value(None) == "—" and f.sd(float("nan")) == "—"


def test_without_an_sd_six_significant_digits():
    f = row_format(0.5, None)
    assert f.value(0.123456789) == "0.123457"
