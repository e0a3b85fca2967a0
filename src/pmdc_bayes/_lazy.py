"""Public names of a package imported on first use (PEP 562), so that importing the
package, or one of its submodules, does not import everything it exports."""

from __future__ import annotations

import importlib

__all__ = ["lazy_names"]


def lazy_names(package: str, where: dict[str, str], namespace: dict):
    """``(__getattr__, __dir__)`` for ``package``: ``where`` maps a name to the relative
    module that defines it (a submodule's own name, ``".name"``, to the submodule); a
    name is imported once and kept in ``namespace`` (the package's globals)."""

    def __getattr__(name):
        if name in where:
            module = importlib.import_module(where[name], package)
            value = module if where[name] == f".{name}" else getattr(module, name)
            namespace[name] = value
            return value
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    def __dir__():
        return sorted(set(namespace) | set(namespace.get("__all__", ())))

    return __getattr__, __dir__
