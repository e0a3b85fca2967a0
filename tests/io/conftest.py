"""A bench-simulator session the loader's tests rewrite as rigs log it."""

import pytest

from pmdc_bayes.simulate.fuzz import fuzz_session


@pytest.fixture(scope="session")
def up_down_session(tmp_path_factory):
    """Seed 22's up-down step (to each sign of the voltage, 0.56 ms between samples),
    logged with its signed voltage and current columns and a steady table."""
    d = tmp_path_factory.mktemp("up_down") / "s"
    fuzz_session(22, out=d, shapes=("up-down",))
    return d
