"""The dependency rule of docs/architecture.md holds in the code: the contracts of
``pyproject.toml`` (import-linter: the layers, private modules, no import cycle among a
package's modules, the simulators beside the stages) are kept, and every module of the
package sits in a layer or beside them, so that a new one cannot escape the rule; and
no module grows past the size of one concern; each subpackage exports the main names
the map gives it."""

import importlib
import inspect
import re
import tomllib
from pathlib import Path

from importlinter.cli import lint_imports

import pmdc_bayes

CONFIG = Path(__file__).resolve().parents[2] / "pyproject.toml"
MAX_LINES = 300


def test_the_import_contracts_are_kept():
    assert lint_imports(config_filename=str(CONFIG), no_cache=True, no_logo=True) == 0


def test_every_module_of_the_package_is_in_a_layer_or_beside_them():
    named = set()
    for contract in tomllib.loads(CONFIG.read_text())["tool"]["importlinter"]["contracts"]:
        for layer in contract.get("layers", []):
            named |= {m.strip() for m in layer.replace("|", ":").split(":")}
        named |= set(contract.get("source_modules", []))
    top = {f"pmdc_bayes.{p.stem}" if p.is_file() else f"pmdc_bayes.{p.name}"
           for p in Path(pmdc_bayes.__file__).parent.iterdir()
           if (p.suffix == ".py" and p.stem != "__init__") or (p / "__init__.py").is_file()}
    assert top - named == set()


def test_no_module_of_the_package_is_over_300_lines():
    """A module holds one concern: past 300 lines it holds more, and is split."""
    root = Path(pmdc_bayes.__file__).parent
    long = {str(p.relative_to(root)): n for p in root.rglob("*.py")
            if (n := len(p.read_text(encoding="utf-8").splitlines())) > MAX_LINES}
    assert long == {}


def test_each_subpackage_exports_the_main_names_the_map_gives_it():
    """docs/architecture.md's table names each subpackage's main names: the subpackage
    gives each of them (imported on first use), so the map and the code agree."""
    doc = (CONFIG.parent / "docs" / "architecture.md").read_text(encoding="utf-8")
    rows = re.findall(r"^\| `([\w/]+)/` \|.*\| (.*) \|\s*$", doc, re.M)
    assert len(rows) >= 10
    missing = {}
    for folder, names in rows:
        package = importlib.import_module("pmdc_bayes." + folder.replace("/", "."))
        for name in re.findall(r"`([\w.]+)`", names):
            obj = package
            for part in name.split("."):
                obj = getattr(obj, part, None)
            # a main name is a function, a class or a constant; a module only on its way
            if obj is None or inspect.ismodule(obj):
                missing.setdefault(folder, []).append(name)
    assert missing == {}
