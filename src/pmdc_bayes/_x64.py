"""64-bit floats where the package computes, without changing the caller's settings.

The motor is stiff (La/Ra ≈ 1 ms against a mechanical time constant ≈ 1 s), so every
computation of this package runs with JAX's 64-bit mode on.  :func:`x64` switches it
on for the duration of a call (JAX's thread-local ``enable_x64`` context), so
importing or calling the package never flips ``jax_enable_x64`` for the caller.

:func:`to_device` puts a host array on the device as it is: ``jnp.asarray`` of a NumPy
array makes (and, with a disk cache, looks up) a small program per shape and dtype,
which a run pays some thirty times before its first fit.
"""

from __future__ import annotations

import functools

import jax
import numpy as np

__all__ = ["x64", "to_device"]


def x64(fn):
    """Decorate ``fn`` so that it runs with JAX's 64-bit mode on."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        with jax.enable_x64(True):
            return fn(*args, **kwargs)

    return wrapper


def to_device(x) -> jax.Array:
    """``x`` as a JAX array: a NumPy array is transferred without a program (its dtype
    kept, under the 64-bit mode of :func:`x64`; a Python number becomes a NumPy one, of
    a strong type); a JAX array or a tracer is returned as it is."""
    if isinstance(x, jax.Array):
        return x
    return jax.device_put(np.asarray(x))
