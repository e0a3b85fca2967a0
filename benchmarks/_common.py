"""Helpers shared by the benchmark scripts: report sections, baseline import, peak memory."""

from __future__ import annotations

import importlib.util
import os
import re
import resource
import subprocess
import sys
import time
from datetime import UTC, datetime
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
REPORT = ROOT / "reports" / "benchmarks.md"


def replace_section(path: Path, title: str, section: str) -> None:
    """Replace the ``## {title}`` section of the markdown file ``path`` (up to the next
    ``## `` heading) with ``section``, or append it; its ``### `` subsections that
    ``section`` does not write again (measurements of other runs) are kept after it,
    other sections are kept and the file is created if missing."""
    text = path.read_text(encoding="utf-8") if path.exists() else "# Benchmarks\n"
    lines = text.splitlines()
    head = f"## {title}"
    kept: list[str] = []
    try:
        start = next(k for k, line in enumerate(lines) if line.strip() == head)
        end = next((k for k in range(start + 1, len(lines)) if lines[k].startswith("## ")),
                   len(lines))
        before, after = lines[:start], lines[end:]
        kept = _subsections(lines[start + 1:end], exclude=section.splitlines())
    except StopIteration:
        before, after = lines, []
    while before and not before[-1].strip():
        before.pop()
    new = [*before, "", *section.rstrip("\n").splitlines()]
    if kept:
        new += ["", *kept]
    if after:
        new += ["", *after]
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(new) + "\n", encoding="utf-8")


def _subsections(lines: list[str], exclude: list[str]) -> list[str]:
    """The ``### `` subsections of ``lines`` whose headings are not among ``exclude``."""
    out: list[str] = []
    keep = False
    for line in lines:
        if line.startswith("### "):
            keep = line.strip() not in {e.strip() for e in exclude}
        if keep:
            out.append(line)
    while out and not out[-1].strip():
        out.pop()
    return out


def write_table_section(title: str, intro: str, header, align, rows) -> None:
    """Replace the ``## {title}`` section of ``reports/benchmarks.md`` with ``intro`` (a
    paragraph that may hold ``{stamp}``, the UTC time now) and a table of ``rows`` under
    ``header``, ``align`` giving each column's markdown alignment (``---`` or ``---:``);
    say so on stdout."""
    stamp = datetime.now(UTC).strftime("%Y-%m-%d %H:%M UTC")
    lines = [f"## {title}", "", intro.replace("{stamp}", stamp), "",
             "| " + " | ".join(header) + " |", "|" + "|".join(align) + "|"]
    lines += ["| " + " | ".join(row) + " |" for row in rows]
    replace_section(REPORT, title, "\n".join(lines) + "\n")
    print(f"updated {REPORT}")


def load_baseline():
    """``benchmarks/baseline.py`` as a module (the benchmarks are not a package)."""
    spec = importlib.util.spec_from_file_location("pmdc_baseline", ROOT / "benchmarks" /
                                                  "baseline.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def cli_command() -> list[str]:
    """The ``pmdc-bayes`` console script of this interpreter's environment (or
    ``python -m pmdc_bayes`` if the script is missing)."""
    script = Path(sys.executable).with_name("pmdc-bayes")
    return [str(script)] if script.exists() else [sys.executable, "-m", "pmdc_bayes"]


_GNU_TIME = Path("/usr/bin/time")


def run_measured(cmd: list[str], *, env: dict | None = None, cwd: Path | None = None,
                 log: Path) -> dict:
    """Run ``cmd`` to completion; its wall time (s), exit code and peak resident memory
    (MiB) with how it was measured.  Output goes to ``log``.

    Peak memory comes from GNU ``/usr/bin/time -v`` when present (this process only);
    otherwise from ``getrusage(RUSAGE_CHILDREN).ru_maxrss``, which is the largest of
    all children waited for so far.
    """
    gnu = _GNU_TIME.exists()
    rss_file = log.with_suffix(".time")
    full = [str(_GNU_TIME), "-v", "-o", str(rss_file), *cmd] if gnu else cmd
    t0 = time.perf_counter()
    with open(log, "w", encoding="utf-8") as out:
        proc = subprocess.run(full, env={**os.environ, **(env or {})}, cwd=cwd, stdout=out,
                              stderr=subprocess.STDOUT, check=False)
    wall = time.perf_counter() - t0
    peak, how = None, None
    if gnu and rss_file.exists():
        m = re.search(r"Maximum resident set size \(kbytes\): (\d+)", rss_file.read_text())
        if m:
            peak, how = int(m.group(1)) / 1024.0, "GNU time -v"
    if peak is None:
        peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024.0
        how = "getrusage(RUSAGE_CHILDREN), largest child so far"
    return {"wall": wall, "returncode": proc.returncode, "peak_mib": peak, "peak_how": how}


def rate(k: int, n: int, digits: int = 0) -> str:
    """``k/n`` as a percentage with its exact (Clopper–Pearson) 95 % interval."""
    from scipy import stats

    if not n:
        return "–"
    lo = float(stats.beta.ppf(0.025, k, n - k + 1)) if k else 0.0
    hi = float(stats.beta.ppf(0.975, k + 1, n - k)) if k < n else 1.0
    return (f"{k}/{n} ({100 * k / n:.{digits}f} %; 95 % interval {100 * lo:.{digits}f}–"
            f"{100 * hi:.{digits}f} %)")
