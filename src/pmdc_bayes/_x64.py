"""64-bit floats where the package computes, without changing the caller's settings.

The motor is stiff (La/Ra ≈ 1 ms against a mechanical time constant ≈ 1 s), so every
computation of this package runs with JAX's 64-bit mode on.  :func:`x64` switches it
on for the duration of a call (JAX's thread-local ``enable_x64`` context), so
importing or calling the package never flips ``jax_enable_x64`` for the caller.
"""

from __future__ import annotations

import functools

import jax

__all__ = ["x64"]


def x64(fn):
    """Decorate ``fn`` so that it runs with JAX's 64-bit mode on."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        with jax.enable_x64(True):
            return fn(*args, **kwargs)

    return wrapper
