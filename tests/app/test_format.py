"""Values shown to people are rounded to their uncertainty, a row on one scale."""

import pytest

from pmdc_bayes._format import off_by, row_format, signed


@pytest.mark.parametrize("value, sd, shown, shown_sd, suffix", [
    (0.0619991, 3.2e-6, "61.9991", "0.0032", "×1e-3 "),
    (1.99507, 0.0575, "1.995", "0.058", ""),
    (1.99311e-05, 7.17e-08, "19.931", "0.072", "×1e-6 "),
    (7.27e-5, 7.61e-4, "70", "760", "×1e-6 "),      # an sd larger than the value
    (12345.6, 78.0, "12.346", "0.078", "×1e3 "),
    (-3.2e-3, 1e-4, "-3.20", "0.10", "×1e-3 "),
    # an sd whose rounding carries into the next power of ten keeps two digits
    (1.23e-3, 0.9962e-3, "1.2", "1.0", "×1e-3 "),
    (0.5012, 0.0996, "0.50", "0.10", ""),
    (1234.0, 99.7, "1230", "100", ""),
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


@pytest.mark.parametrize("value, estimate, sd, shown", [
    (0.0620199, 0.0619991, 3.2e-6, ("+0.034", "+6.5")),
    (5.5825e-5, 4.496e-5, 4.2e-8, ("+24", "+259")),
    (8.34727, 8.49921, 7.7e-4, ("-1.8", "-197")),
    # the closed form at the estimate to rounding error (a bench value the data leave
    # alone): no "-4e-14 %, -3e-14 sd"
    (5.621e-3 * (1 - 4.4e-16), 5.621e-3, 1e-4, ("0", "0")),
    (1.0, 1.0, 0.1, ("0", "0")),
])
def test_how_far_the_closed_form_is_off_stops_at_a_hundredth_of_an_sd(value, estimate, sd,
                                                                       shown):
    assert off_by(value, estimate, sd) == shown


def test_off_by_says_nothing_without_a_value_an_estimate_or_an_sd():
    assert off_by(None, 1.0, 0.1) is None and off_by(1.0, 0.0, 0.1) is None
    assert off_by(1.0, 2.0, 0.0) is None and off_by(1.0, 2.0, float("nan")) is None
    assert signed(-0.0746) == "-0.075" and signed(0.004, 0.01) == "0"
