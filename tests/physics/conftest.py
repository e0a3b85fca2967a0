import pytest


@pytest.fixture(autouse=True)
def _physics_in_64_bits(jax_x64):
    """The tests here call the physics directly, as the package calls it inside its
    64-bit context."""
