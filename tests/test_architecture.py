"""The dependency rule of docs/architecture.md holds in the code: the layers contract of
``pyproject.toml`` (import-linter) is kept, every module of the package sits in a layer
or beside them, and no import cycle joins the package's modules but the one the public
``Session.from_arrays`` makes."""

import tomllib
from pathlib import Path

import grimp
from importlinter.cli import lint_imports

import pmdc_bayes

ROOT = Path(__file__).resolve().parents[1]
CONFIG = ROOT / "pyproject.toml"


def _contracts():
    return tomllib.loads(CONFIG.read_text())["tool"]["importlinter"]["contracts"]


def _cycles(graph) -> list[set]:
    """The strongly connected groups of more than one module (Tarjan, iteratively)."""
    adj = {m: sorted(graph.find_modules_directly_imported_by(m)) for m in graph.modules}
    index, low, stack, on, out, counter = {}, {}, [], set(), [], [0]
    for root in sorted(adj):
        if root in index:
            continue
        work = [(root, iter(adj[root]))]
        index[root] = low[root] = counter[0]
        counter[0] += 1
        stack.append(root)
        on.add(root)
        while work:
            v, it = work[-1]
            w = next(it, None)
            if w is not None:
                if w not in index:
                    index[w] = low[w] = counter[0]
                    counter[0] += 1
                    stack.append(w)
                    on.add(w)
                    work.append((w, iter(adj[w])))
                elif w in on:
                    low[v] = min(low[v], index[w])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[v])
            if low[v] == index[v]:
                group = set()
                while True:
                    w = stack.pop()
                    on.discard(w)
                    group.add(w)
                    if w == v:
                        break
                if len(group) > 1:
                    out.append(group)
    return out


def test_the_layers_contract_is_kept():
    assert lint_imports(config_filename=str(CONFIG), no_cache=True, no_logo=True) == 0


def test_every_module_of_the_package_is_in_a_layer_or_beside_them():
    named = set()
    for contract in _contracts():
        for layer in contract.get("layers", []):
            named |= {m.strip() for m in layer.replace("|", ":").split(":")}
        named |= set(contract.get("source_modules", []))
    top = {f"pmdc_bayes.{p.stem}" if p.is_file() else f"pmdc_bayes.{p.name}"
           for p in Path(pmdc_bayes.__file__).parent.iterdir()
           if (p.suffix == ".py" and p.stem != "__init__") or (p / "__init__.py").is_file()}
    assert top - named == set()


def test_no_import_cycle_but_the_sessions_from_arrays():
    graph = grimp.build_graph("pmdc_bayes", exclude_type_checking_imports=True, cache_dir=None)
    cycles = _cycles(graph)
    # Session.from_arrays writes the arrays as a session's files and reads them back
    # with the loader, which makes Sessions
    allowed = {"pmdc_bayes.io.session", "pmdc_bayes.io.arrays", "pmdc_bayes.io.loader"}
    assert all(allowed <= c and all(m.startswith("pmdc_bayes.io.") for m in c)
               for c in cycles), cycles
    assert len(cycles) <= 1


def test_the_cycle_finder_finds_a_cycle():
    class Graph:
        modules = {"a", "b", "c", "d"}

        @staticmethod
        def find_modules_directly_imported_by(m):
            return {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}[m]

    assert _cycles(Graph()) == [{"a", "b", "c"}]
