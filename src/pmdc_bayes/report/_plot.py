"""Matplotlib set-up for the report (non-interactive backend) and shared helpers."""

from __future__ import annotations

import io
import math
import warnings

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

__all__ = ["plt", "png", "COLORS", "LABELS", "scale_of", "UNIT_TEXT", "arviz_plot"]

COLORS = {"measured": "0.35", "closed_form": "tab:orange", "map": "tab:blue",
          "mean": "tab:green", "truth": "tab:purple", "published": "tab:red"}
LABELS = {"closed_form": "closed form", "map": "MAP", "mean": "posterior predictive mean",
          "truth": "truth (simulated session)"}
UNIT_TEXT = {"Ra": "Ω", "La": "H", "K": "V·s/rad", "B": "N·m·s/rad", "J": "kg·m²",
             "Tc": "N·m"}

plt.rcParams.update({"figure.dpi": 110, "savefig.dpi": 110, "font.size": 9,
                     "axes.titlesize": 10, "legend.fontsize": 8, "axes.grid": True,
                     "grid.alpha": 0.3})


def png(fig) -> bytes:
    """The figure as PNG bytes; the figure is closed."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", bbox_inches="tight")
    plt.close(fig)
    return buf.getvalue()


def scale_of(name: str, value: float) -> tuple[float, str]:
    """A power-of-ten factor and an axis label for a parameter, e.g. ``J (10⁻⁴ kg·m²)``."""
    unit = UNIT_TEXT.get(name, "")
    if value == 0 or not math.isfinite(value):
        return 1.0, f"{name} ({unit})"
    e = math.floor(math.log10(abs(value)))
    if -1 <= e <= 2:
        return 1.0, f"{name} ({unit})"
    sup = str(e).translate(str.maketrans("-0123456789", "⁻⁰¹²³⁴⁵⁶⁷⁸⁹"))
    return 10.0**-e, f"{name} (10{sup} {unit})"


def arviz_plot(fn, *args, **kwargs):
    """Call an ArviZ plotting function.  ArviZ 0.23's matplotlib backend passes a dict
    to ``normalize_kwargs``, which matplotlib 3.11 deprecates; the plot is unaffected,
    so that one notice is silenced here (and only here)."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="Passing a dict or None as alias_mapping",
                                category=matplotlib.MatplotlibDeprecationWarning)
        return fn(*args, **kwargs)
