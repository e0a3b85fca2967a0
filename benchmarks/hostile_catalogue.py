"""A catalogue of hostile or awkward inputs and faults, run through the installed CLI.

Each case copies a bundled session (``data/demo``, ``data/paper``, or "mini": the demo
cut to one step trace of 251 samples, for fast fits) into a fresh temporary directory,
breaks one thing, runs ``python -m pmdc_bayes ...`` there (own TMPDIR, so error logs
stay in the case directory; one PMDC_BAYES_CACHE for the whole run) and classifies it:

  clean         an expected exit code; on failure stderr is exactly one ``pmdc-bayes:``
                line holding one of the case's keywords; no "Traceback"
  traceback     "Traceback" in the output, exit 1 without a ``pmdc-bayes:`` line, or an
                unexpected exit 4 (internal error: its saved traceback's last line shown)
  silent-wrong  exit 0 where the case expects an error, or a warning (a keyword on stderr
                or on a stdout line saying "warning")
  data-lost     a user's file gone or changed, a hidden temporary left behind, a failed
                command's --out directory left behind, or a failed post-check
  hang          the command outlived its timeout (killed)
  misleading    any other deviation: no keyword in the message, an unexpected exit code,
                not exactly one stderr line (argparse's extra "usage:" line included)

Run from the repository root, in the environment where pmdc_bayes is installed:

    python benchmarks/hostile_catalogue.py               # every case (~20 min on 2 cores)
    python benchmarks/hostile_catalogue.py --list        # names and classes
    python benchmarks/hostile_catalogue.py --only csv-   # cases whose name holds 'csv-'

Cases needing an unreadable file or a read-only directory are skipped as root.
Standard library and numpy only.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "data"
STEP, TOML = "s/step_12v97.csv", "s/session.toml"
IS_ROOT = hasattr(os, "geteuid") and os.geteuid() == 0
SHARED = Path()     # the run's temporary directory (cache, base run), set in main()


# ---------------------------------------------------------------- setup building blocks
# A setup is a function of the case directory d; the helpers below return such steps.
def S(*steps): return lambda d: [step(d) for step in steps]


def copy(name): return lambda d: shutil.copytree(DATA / name, d / "s")


def demo(*steps): return S(copy("demo"), *steps)


def paper(*steps): return S(copy("paper"), *steps)


def mini(*steps): return S(MINI, *steps)


def raw(rel, fn): return lambda d: (d / rel).write_bytes(fn((d / rel).read_bytes()))


def chmod(rel, mode): return lambda d: os.chmod(d / rel, mode)


def link(rel, target):
    return lambda d: ((d / rel).unlink(missing_ok=True), os.symlink(target, d / rel))


def mkdir(rel):
    return lambda d: ((d / rel).unlink() if (d / rel).is_file() else None,
                      (d / rel).mkdir(parents=True, exist_ok=True))


def put(rel, data):
    data = data if isinstance(data, bytes) else data.encode("utf-8")
    return lambda d: ((d / rel).parent.mkdir(parents=True, exist_ok=True),
                      (d / rel).write_bytes(data))


def MINI(d, names=("step_12v97",)):
    """The demo with its first trace only, every 10th sample (fits in ~30 s once compiled);
    the trace's block repeated under each of ``names``."""
    (d / "s").mkdir()
    head, first = (DATA / "demo" / "session.toml").read_text().split("[[trace]]")[:2]
    blocks = [first.replace('"step_12v97"', f'"{n}"', 1) for n in names]
    (d / TOML).write_text(head + "".join("[[trace]]" + b for b in blocks))
    shutil.copy(DATA / "demo" / "table2.csv", d / "s")
    rows = (DATA / "demo" / "step_12v97.csv").read_text().splitlines()
    (d / STEP).write_text("\n".join([rows[0], *rows[1::10]]) + "\n")


def text(rel, old, new):
    """Replace the first ``old`` (which must be there) by ``new`` in a text file."""
    def step(d):
        t = (d / rel).read_text(encoding="utf-8")
        assert old in t, f"setup: {old!r} not in {rel}"
        (d / rel).write_text(t.replace(old, new, 1), encoding="utf-8")
    return step


def lines(rel, fn):
    """Rewrite a text file through ``fn(list of lines) -> list of lines``."""
    return lambda d: (d / rel).write_text("\n".join(fn((d / rel).read_text().splitlines()))
                                          + "\n")


def col(rel, k, fn):
    """Transform numeric column ``k`` of a comma-separated file with ``fn(array)``."""
    def step(d):
        head, *rows = (d / rel).read_text().splitlines()
        a = np.array([[float(x) for x in r.split(",")] for r in rows])
        a[:, k] = fn(a[:, k])
        (d / rel).write_text("\n".join([head, *(",".join(f"{v:.10g}" for v in r) for r in a)])
                             + "\n")
    return step


def fit_into(d):
    """Setup step: a real ``fit s --no-mcmc --out run`` in ``d``."""
    r = subprocess.run([sys.executable, "-m", "pmdc_bayes", "fit", "s", "--no-mcmc", "--out",
                        "run"], cwd=d, env=_env(d), capture_output=True, text=True, timeout=900)
    if not (d / "run" / "summary.json").is_file():
        raise RuntimeError(f"setup fit failed (exit {r.returncode}): {r.stderr[-500:]}")


def base_run(d):
    """Setup step: a copy of the shared base run (fit of mini, made once) as ``d/run``."""
    if not (SHARED / "base" / "run").is_dir():
        (SHARED / "base").mkdir(exist_ok=True)
        S(MINI, fit_into)(SHARED / "base")
    shutil.copytree(SHARED / "base" / "run", d / "run", symlinks=True)


def no_copy(d):
    """Setup step: drop the run's copy of its session (as in runs written before copies)."""
    shutil.rmtree(d / "run" / "session")


def session_moved(d):
    p = d / "run" / "summary.json"
    s = json.loads(p.read_text())
    s["session"]["path"] = str(d / "gone")
    p.write_text(json.dumps(s))


def three_trace_figures(d):
    """Post-check: three traces whose names sanitise alike need three figure files."""
    figs = sorted(p.name for p in (d / "run" / "figures").glob("trace_*.png"))
    return None if len(figs) >= 3 else f"3 traces but trace figures {figs}"


def long_step(d, n=1_000_000):
    """The demo's 12.97 V step (25 s) as ``n`` noiseless samples (~40 MB)."""
    t = np.linspace(0.0, 25.0, n)
    w = np.where(t < 0.5, 0.0, 1590 * (1 - np.exp(-(t - 0.5) / 1.18)))
    i = np.where(t < 0.5, 0.0, 0.2 + 1.3 * np.exp(-(t - 0.5) / 1.18))
    np.savetxt(d / STEP, np.column_stack([t, w, i]), fmt="%.8g", delimiter=",",
               header="t,speed,ia", comments="")


# ---------------------------------------------------------------- the catalogue
@dataclass
class Case:
    name: str
    cls: str
    setup: Callable
    argv: list
    codes: tuple | int = 2         # the expected exit code(s)
    keywords: tuple = ()            # one of these must be in the message (case-insensitive)
    warn: bool = False              # exit 0 is fine if a keyword is printed as a warning
    keep: tuple = ("s",)            # paths (relative to the case dir) that must not change
    check: Callable | None = None   # post-check: d -> None, or what was lost
    sig: tuple | None = None        # (signal, seconds after the start or a glob to wait for)
    env: dict | None = None         # extra environment: paths relative to the case dir
    fit: bool = False               # may run a fit: the long timeout
    root_skip: str = ""             # why the case means nothing when run as root
    same: str = ""                  # exit 0 is fine if stdout equals this pristine session's


C, CF, RUN = Case, ["closed-form", "s"], ["report", "run"]
CFJ = [*CF, "--json"]    # with same="demo": accepted if it reads the same numbers
FIT = ["fit", "s", "--no-mcmc", "--out", "run"]
OUT = FIT[:-1]      # fit ... --out (the directory follows)
DL, TB, SW, HG, MM = "data loss", "traceback", "silently wrong", "hang", "misleading msg"
ENC = ("UTF-8", "encoding", "Latin-1", "Windows-1252")
SEMI = ("semicolon", "delimiter", "';'")
TAB = ("tab-separated", "tabs", "delimiter", "tab character", "separated by tab")
SIGN, OPK, LOOP = ("sign", "negative", "revers"), ("chopper", "operating_point"), ("link", "loop")
NOT_RUN, SUM = ("run directory", "session"), ("summary.json",)
ROW1 = "0.01,3,-0.001476816299"     # line 3 of step_12v97.csv
OP_I, TAU = "current = 0.22 ", "tau = 1.1598  "    # in the paper's session.toml
RPM, R400 = 60 / (2 * np.pi), "1" + "0" * 400
HANDMADE = lines(TOML, lambda ls: ls[3:])    # drop the "Generated by simulate" header
USER_TRACE = text(TOML, '[[trace]]\nname = "step_12v97"',
                  '[[trace]]\nname = "mine"\nkind = "step"\nfile = "my_bench.csv"\ncolumns = '
                  '{ time = "t", speed = "speed" }\nvoltage = [[0, 12]]\n\n[[trace]]\n'
                  'name = "step_12v97"')
RANDOM = np.random.default_rng(1).integers(0, 256, 5000, np.uint8).tobytes()
FOUR = ("step_12v97", "step_6v49", "load_change", "current_capture")
CASES = [
    # --- data loss ---------------------------------------------------------------------
    C("fit-out-is-session", DL, MINI, [*OUT, "s", "--force"], 2, ("session",), fit=True),
    C("fit-out-is-regular-file", DL, mini(put("notes.txt", "mine")),
      [*OUT, "notes.txt", "--force"], 2, ("directory", "file"), keep=("s", "notes.txt"), fit=True),
    C("fit-out-user-folder", DL, mini(put("mine/a.txt", "x"), put("mine/b.csv", "1,2")),
      [*OUT, "mine", "--force"], 2, NOT_RUN, keep=("s", "mine"), fit=True),
    C("fit-out-user-folder-with-summary-json", DL,
      mini(put("mine/summary.json", '{"trial": 3}'), put("mine/thesis.docx", "ch. 1")),
      [*OUT, "mine", "--force"], 2, NOT_RUN, keep=("s", "mine"), fit=True),
    C("fit-out-symlink-to-session", DL, mini(link("ln", "s")), [*OUT, "ln", "--force"], 2,
      ("session", "link"), keep=("s", "ln"), fit=True),
    C("fit-out-empty-string-is-cwd", DL, mini(put("notes.txt", "mine")), [*OUT, "", "--force"],
      2, NOT_RUN, keep=("s", "notes.txt"), fit=True),
    C("fit-sigint-over-earlier-run", DL, mini(base_run), [*FIT, "--force"], (130, -2),
      keep=("s", "run"), sig=(signal.SIGINT, 8), fit=True),
    C("fit-sigterm-over-earlier-run", DL, mini(base_run), [*FIT, "--force"], (130, 143, -15),
      keep=("s", "run"), sig=(signal.SIGTERM, 8), fit=True),
    C("fit-sigint-while-writing-over-earlier-run", DL, mini(base_run), [*FIT, "--force"],
      (130, -2), keep=("s", "run"), sig=(signal.SIGINT, ".run.*"), fit=True),
    C("fit-trace-names-sanitise-alike", DL, lambda d: MINI(d, ("a/b", "a_b", "a b")), FIT,
      (0, 1, 3), check=three_trace_figures, fit=True),
    C("simulate-force-over-handmade-session", DL,
      demo(HANDMADE, put("s/notes.txt", "mine"), lambda d: shutil.copy(d / "s/plan.toml", d)),
      ["simulate", "plan.toml", "--out", "s", "--force"], 2, ("simulate",)),
    C("simulate-force-deletes-user-trace", DL,
      demo(put("s/my_bench.csv", "t,speed\n0,0\n"), put("s/notes.txt", "mine"), USER_TRACE),
      ["simulate", "s/plan.toml", "--out", "s", "--force"], 2, ("changed since",),
      keep=("s/my_bench.csv", "s/notes.txt", "s/plan.toml", "s/session.toml")),
    C("simulate-out-is-regular-file", DL, demo(put("notes.txt", "mine")),
      ["simulate", "s/plan.toml", "--out", "notes.txt", "--force"], 2, ("directory",),
      keep=("s", "notes.txt")),
    C("report-through-symlinked-report.md", DL,
      S(base_run, put("thesis.md", "my thesis"), link("run/report.md", "../thesis.md")), RUN,
      0, keep=("thesis.md",)),
    # --- tracebacks ----------------------------------------------------------------------
    C("csv-latin1-header", TB, demo(raw(STEP, lambda b: b.replace(b"ia", b"ia,temp \xb0C", 1))),
      CF, 2, ENC),
    C("csv-utf16-bom-tab (Excel Unicode text)", TB,
      demo(raw(STEP, lambda b: b.replace(b",", b"\t").decode().encode("utf-16"))), CFJ, (0, 2),
      ("UTF-16", *TAB), same="demo"),
    C("csv-utf16-no-bom", TB, demo(raw(STEP, lambda b: b.decode().encode("utf-16-le"))), CF, 2,
      ("UTF-16", "binary", "encoding")),
    C("csv-binary", TB, demo(put(STEP, RANDOM)), CF, 2, ("binary",)),
    C("csv-nul-byte-after-4k", TB, demo(raw(STEP, lambda b: b[:6000] + b"\0" + b[6000:])), CF,
      2, ("NUL", "binary", "null")),
    C("csv-field-200k-chars", TB,
      demo(lines(STEP, lambda ls: [ls[0] + ",note", ls[1] + ",x", ls[2] + "," + "y" * 200_000,
                                   *(r + ",z" for r in ls[3:])])),
      CF, 2, ("field", "characters", "long")),
    C("csv-unclosed-quote", TB, demo(text(STEP, ROW1, '"' + ROW1)), CF, 2, ("quote",)),
    C("csv-unreadable", TB, demo(chmod(STEP, 0)), CF, 2, ("permission",),
      root_skip="root reads a chmod 000 file"),
    C("toml-unreadable", TB, demo(chmod(TOML, 0)), CF, 2, ("permission",),
      root_skip="root reads a chmod 000 file"),
    C("cf-K-zero (d*Vs = Ra*I)", TB,
      paper(text(TOML, "value = 8.5 ", "value = 8.4 "), text(TOML, OP_I, "current = 2.0 ")),
      CF, 2, OPK),
    C("cf-K-negative", TB, paper(text(TOML, OP_I, "current = 5.0 ")), CF, 2, OPK),
    C("toml-int-10**400", TB, paper(text(TOML, "value = 8.5 ", f"value = {R400} ")), CF, 2,
      ("bench.Ra",)),
    C("toml-nan-tau", TB, paper(text(TOML, TAU, "tau = nan ")), CF, 2, ("tau",)),
    C("fit-seed-negative", TB, MINI, [*FIT, "--seed", "-1"], 2, ("seed",), fit=True),
    C("fit-out-below-regular-file", TB, mini(put("notes.txt", "mine")),
      [*OUT, "notes.txt/run"], 2, ("directory", "notes.txt"), keep=("s", "notes.txt"), fit=True),
    C("fit-out-name-too-long", TB, MINI, [*OUT, "x" * 300], 2, ("long",), fit=True),
    C("fit-out-in-read-only-dir", TB, mini(mkdir("ro"), chmod("ro", 0o555)), [*OUT, "ro/run"],
      2, ("permission", "read-only"), fit=True, root_skip="root writes into a chmod 555 dir"),
    C("report-garbage-posterior.nc", TB, S(base_run, put("run/posterior.nc", b"\x89HDF\0" * 99)),
      RUN, 2, ("posterior.nc",)),
    C("report-summary-empty-object", TB, S(base_run, put("run/summary.json", "{}")), RUN, 2, SUM),
    C("report-summary-not-json", TB, S(base_run, put("run/summary.json", "garbage")), RUN, 2, SUM),
    C("report-no-summary", TB, put("run/report.md", "# old"), RUN, 2, SUM),
    C("report-session-gone (no run copy)", TB, S(base_run, no_copy, session_moved), RUN,
      2, ("session", "missing")),
    C("report-figures-is-a-file", TB,
      S(base_run, lambda d: shutil.rmtree(d / "run/figures"), put("run/figures", "mine")), RUN,
      2, ("figures",)),
    C("report-cache-is-a-file", TB, S(base_run, put("cachefile", "mine")), RUN, 0,
      keep=("cachefile",), env={"PMDC_BAYES_CACHE": "cachefile"}),
    C("fit-cache-below-a-file", TB, mini(put("cachefile", "mine")), FIT, (0, 1, 3),
      keep=("s", "cachefile"), env={"PMDC_BAYES_CACHE": "cachefile/sub"}, fit=True),
    C("fit-cache-read-only", TB, mini(mkdir("ro"), chmod("ro", 0o555)), FIT, (0, 1, 3),
      env={"PMDC_BAYES_CACHE": "ro"}, fit=True, root_skip="root writes into a chmod 555 dir"),
    # --- silently wrong: exit 0 is clean only with a warning naming a keyword ---------------
    C("fit-speed-unit-slip (x60/2pi)", SW, mini(col(STEP, 1, lambda w: w * RPM)), FIT,
      (0, 2, 3), ("unit",), warn=True, fit=True),
    C("cf-op-speed-rpm-declared-rad/s", SW,
      demo(text(TOML, "speed = 241.6106288", f"speed = {241.6106288 * RPM:.6f}")), CF, (0, 2),
      ("unit", "rpm", "disagree", "inconsistent"), warn=True),
    C("cf-reversed-speed-sign", SW, demo(col(STEP, 1, lambda w: -w)), CF, (0, 2), SIGN,
      warn=True),
    C("fit-reversed-speed-sign", SW, mini(col(STEP, 1, lambda w: -w)), FIT, (0, 2, 3), SIGN,
      warn=True, fit=True),
    C("csv-comma-decimals", SW, demo(lines(STEP, lambda ls: [ls[0], *(r.replace(".", ",")
                                                                  for r in ls[1:])])),
      CFJ, (0, 2), ("decimal comma", "decimal separator", "comma"), same="demo"),
    C("csv-rows-with-extra-fields", SW,
      demo(lines(STEP, lambda ls: [r + ",7" if k % 10 == 5 else r for k, r in enumerate(ls)])),
      CF, (0, 2), ("fields", "extra"), warn=True),
    C("csv-duplicated-header-name", SW,
      demo(lines(STEP, lambda ls: [ls[0] + ",speed", *(r + ",0" for r in ls[1:])])), CF,
      (0, 2), ("duplicate", "twice", "more than once"), warn=True),
    C("cf-chopper-load-above-motor-torque", SW,
      paper(text(TOML, "load_torque = 0.0 ", "load_torque = 0.5 ")), CF, (0, 2),
      ("load_torque", "load torque"), warn=True),
    C("cf-duty-percent-without-unit", SW, demo(text(TOML, "duty = 0.7", "duty = 70")), CF,
      (0, 2), ("%",), warn=True),
    C("cf-duty-fraction-declared-percent", SW,
      demo(text(TOML, "units = { supply", 'units = { duty = "%", supply')), CF, (0, 2),
      ("duty",), warn=True),
    C("cf-step-reading-0V", SW, paper(text(TOML, "voltage = 12.97 ", "voltage = 0.0 ")), CF,
      (0, 2), ("voltage",), warn=True),
    C("cf-step-reading-tau-1e-300", SW, paper(text(TOML, TAU, "tau = 1e-300 ")), CF, (0, 2),
      ("tau", "time constant"), warn=True),
    C("cf-step-reading-final-speed-0", SW,
      paper(text(TOML, "final_speed = 1590", "final_speed = 0")), CF, (0, 2), ("final_speed",),
      warn=True),
    C("report-after-csv-changed (no run copy)", SW,
      mini(fit_into, no_copy, col(STEP, 1, lambda w: w * 1.1)), RUN, (0, 2),
      ("changed", "modified", "differ"), warn=True, fit=True),
    # --- hangs ---------------------------------------------------------------------------------
    C("fit-all-zero-trace", HG, mini(col(STEP, 1, lambda w: 0 * w), col(STEP, 2, lambda i: 0 * i)),
      FIT, (1, 2, 3), fit=True),
    C("fit-constant-trace", HG,
      mini(col(STEP, 1, lambda w: 0 * w + 1590), col(STEP, 2, lambda i: 0 * i + 0.2)), FIT,
      (1, 2, 3), fit=True),
    C("fit-three-samples", HG, mini(lines(STEP, lambda ls: [ls[0], ls[1], ls[100], ls[250]])),
      FIT, (0, 1, 2, 3), fit=True),
    C("cf-one-sample-per-trace", HG, demo(*(lines(f"s/{n}.csv", lambda ls: ls[:2]) for n in FOUR)),
      CF, 2, ("samples",)),
    C("cf-all-zero-speed", HG, demo(col(STEP, 1, lambda w: 0 * w)), CF, 2,
      ("every row", "did not turn", "time constant")),
    C("cf-million-row-trace", HG, demo(long_step), CF, 0),
    # --- misleading messages -----------------------------------------------------------------
    C("csv-semicolon-separated", MM, demo(raw(STEP, lambda b: b.replace(b",", b";"))), CFJ,
      (0, 2), SEMI, same="demo"),
    C("csv-tab-separated", MM, demo(raw(STEP, lambda b: b.replace(b",", b"\t"))), CFJ, (0, 2),
      TAB, same="demo"),
    C("csv-semicolon-comma-decimal (EU Excel)", MM,
      demo(raw(STEP, lambda b: b.replace(b",", b";").replace(b".", b","))), CFJ, (0, 2),
      (*SEMI, "decimal comma"), same="demo"),
    C("csv-excel-sep-line", MM, demo(raw(STEP, lambda b: b"sep=,\n" + b)), CFJ, (0, 2),
      ("sep=",), same="demo"),
    C("csv-comment-first-line", MM, demo(raw(STEP, lambda b: b"# scope log 3\n" + b)), CFJ, 0,
      same="demo"),
    C("csv-empty-cell", MM, demo(text(STEP, ROW1, "0.01,,-0.001476816299")), CF, 2,
      ("empty", "missing")),
    C("csv-is-a-directory", MM, demo(mkdir(STEP)), CF, 2, ("directory",)),
    C("csv-symlink-loop", MM, demo(link(STEP, "step_12v97.csv")), CF, 2, LOOP),
    C("csv-dangling-symlink", MM, demo(link(STEP, "nowhere.csv")), CF, 2, ("link", "dangling")),
    C("csv-crlf-quoted-header", MM, demo(raw(STEP, lambda b: b.replace(
        b"t,speed,ia", b'"t", speed ,ia ').replace(b"\n", b"\r\n"))), CFJ, 0, same="demo"),
    C("toml-utf8-bom", MM, demo(raw(TOML, lambda b: b"\xef\xbb\xbf" + b)), CFJ, 0, same="demo"),
    C("toml-utf16", MM, demo(raw(TOML, lambda b: b.decode().encode("utf-16"))), CFJ, (0, 2),
      ("UTF-16", *ENC), same="demo"),
    C("toml-latin1", MM, demo(text(TOML, 'name = "Simulated', 'name = "Moteur \u00e9'),
                              raw(TOML, lambda b: b.decode().encode("latin-1"))), CF, 2, ENC),
    C("toml-symlink-loop", MM, demo(link(TOML, "session.toml")), CF, 2, LOOP),
    C("session-arg-is-a-csv", MM, copy("demo"), ["closed-form", STEP], 2, ("session",)),
    C("session-dir-empty", MM, mkdir("s"), CF, 2, ("session.toml",)),
    C("local-dir-shadows-bundled-demo", MM, mkdir("demo"), ["closed-form", "demo"], 2,
      ("session.toml", "bundled")),
    C("step-after-last-sample", MM, demo(text(TOML, "[0.5, 12.97]", "[30, 12.97]")), CF, 2,
      ("last sample",)),
]


# ---------------------------------------------------------------- running and judging
def _env(d: Path, extra=None) -> dict:
    (d / "_tmp").mkdir(exist_ok=True)
    env = dict(os.environ, PMDC_BAYES_CACHE=str(SHARED / "cache"), TMPDIR=str(d / "_tmp"))
    env.update({k: str(d / v) for k, v in (extra or {}).items()})
    return env


def snapshot(p: Path) -> dict:
    """Every entry under ``p`` (links not followed): path -> content hash or link target."""
    if p.is_symlink():
        return {str(p): "-> " + os.readlink(p)}
    if p.is_file():
        return {str(p): hashlib.sha256(p.read_bytes()).hexdigest()}
    out = {str(p): "dir"} if p.is_dir() else {}
    for q in sorted(p.iterdir()) if p.is_dir() else []:
        out.update(snapshot(q))
    return out


def data_lost(case, d, before, kept, rc, out_existed) -> str | None:
    for k, sig in kept.items():
        if (now := snapshot(Path(k)).get(k)) != sig:
            return f"{Path(k).relative_to(d)} {'deleted' if now is None else 'changed'}"
    hidden = sorted(Path(q).name for q in listing(d) - before
                    if Path(q).name.startswith(".") and str(Path(q).parent) in before | {str(d)})
    if hidden:
        return "left behind: " + ", ".join(hidden)
    out = d / case.argv[case.argv.index("--out") + 1] if "--out" in case.argv else d
    if rc not in (0, 1, 3) and not out_existed and out != d and os.path.lexists(out):
        return f"the failed command left {out.name}/ behind"
    return case.check(d) if case.check else None


def listing(d: Path) -> set:
    return {str(q) for q in d.rglob("*") if "_tmp" not in q.relative_to(d).parts}


def last_line(out: str, err: str) -> str:
    """The traceback's last line: printed, or in the log file the message names."""
    m = re.search(r"traceback saved to (\S+)", err)
    if "Traceback" not in out + err and m and Path(m.group(1)).is_file():
        return "log: " + [ln for ln in Path(m.group(1)).read_text().splitlines() if ln][-1]
    return ([ln for ln in (out + err).splitlines() if ln.strip()] or [""])[-1]


def same_as_pristine(name: str, out: str) -> bool:
    """Whether ``out`` (JSON) equals ``closed-form --json`` of the bundled session ``name``."""
    d = SHARED / f"pristine-{name}"
    if not d.exists():
        d.mkdir()
        copy(name)(d)
    r = subprocess.run([sys.executable, "-m", "pmdc_bayes", *CFJ], cwd=d, env=_env(d),
                       capture_output=True, text=True, timeout=300)
    try:
        return json.loads(out) == json.loads(r.stdout)
    except ValueError:
        return False


def has_kw(keywords, textv: str) -> bool:
    return not keywords or any(re.search(r"(?<!\w)" + re.escape(k), textv, re.I)
                               for k in keywords)


def classify(case, rc, out, err, lost, same) -> str:
    errs = [ln for ln in err.splitlines() if ln.strip()]
    warned = err + "\n".join(ln for ln in out.splitlines() if "warning" in ln.lower())
    if rc is None:
        return "hang"
    if lost:
        return "data-lost"
    if "Traceback" in out + err or (rc == 4 and case.codes != 4) or \
            (rc == 1 and not (errs and errs[-1].startswith("pmdc-bayes:"))):
        return "traceback"
    codes = case.codes if isinstance(case.codes, tuple) else (case.codes,)
    if rc == 0 and case.same:
        return "clean" if same else "silent-wrong"
    if rc == 0 and (0 not in codes or (case.warn and not has_kw(case.keywords, warned))):
        return "silent-wrong"
    if rc not in codes or (rc > 0 and (len(errs) != 1 or not errs[0].startswith(
            "pmdc-bayes:") or not has_kw(case.keywords, err))):
        return "misleading"
    return "clean"


def run_case(case, d: Path, timeout: float) -> dict:
    case.setup(d)
    env = _env(d, case.env)
    kept = {k: v for rel in case.keep for k, v in snapshot(d / rel).items()}
    before = listing(d)
    out_existed = "--out" in case.argv and os.path.lexists(d / case.argv[
        case.argv.index("--out") + 1])
    t0 = time.monotonic()
    proc = subprocess.Popen([sys.executable, "-m", "pmdc_bayes", *case.argv], cwd=d, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            errors="replace", start_new_session=True)
    sent = False
    try:
        while case.sig and not sent and proc.poll() is None and time.monotonic() - t0 < timeout:
            when = case.sig[1]
            if any(d.glob(when)) if isinstance(when, str) else time.monotonic() - t0 >= when:
                proc.send_signal(case.sig[0])
                sent = True
            time.sleep(0.05)
        out, err = proc.communicate(timeout=max(1.0, timeout - (time.monotonic() - t0)))
        rc = proc.returncode
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)     # the process group this script started
        out, err = proc.communicate()
        rc = None
    if case.sig and not sent:
        raise RuntimeError(f"the command ended (exit {rc}) before the signal was sent")
    lost = data_lost(case, d, before, kept, rc, out_existed)
    same = rc == 0 and bool(case.same) and same_as_pristine(case.same, out)
    outcome = classify(case, rc, out, err, lost, same)
    first = next((ln for ln in err.splitlines() if ln.strip()), "")
    detail = lost or (last_line(out, err) if outcome == "traceback" else first)
    return {"name": case.name, "cls": case.cls, "outcome": outcome, "rc": rc, "first": first,
            "detail": detail}


def main(argv=None) -> int:
    global SHARED
    ap = argparse.ArgumentParser(description="Run hostile inputs through the pmdc-bayes CLI.")
    ap.add_argument("--only", metavar="SUBSTR", help="run only cases whose name holds SUBSTR")
    ap.add_argument("--list", action="store_true", help="list the cases and exit")
    ap.add_argument("--timeout", type=float, default=120, help="seconds per case (default 120)")
    ap.add_argument("--fit-timeout", type=float, default=600,
                    help="seconds per case that may fit (default 600: the first compiles)")
    ap.add_argument("--keep-temp", action="store_true", help="keep the temporary directories")
    args = ap.parse_args(argv)
    cases = [c for c in CASES if not args.only or args.only in c.name]
    if args.list:
        for c in cases:
            print(f"{c.name:<42} {c.cls:<15} {'(may fit)' if c.fit else ''}")
        print(f"{len(cases)} cases")
        return 0
    if not (DATA / "demo" / "session.toml").is_file():
        sys.exit(f"{DATA}: the bundled sessions are missing; run from a source checkout")
    SHARED = Path(tempfile.mkdtemp(prefix="pmdc-hostile-"))
    results, skipped = [], []
    print(f"{'case':<42} {'class':<15} {'outcome':<13} {'exit':>5}  first line of stderr")
    try:
        for k, case in enumerate(cases):
            row = f"{case.name:<42} {case.cls:<15} "
            if case.root_skip and IS_ROOT:
                skipped.append((case.name, f"running as root: {case.root_skip}"))
                print(row + f"{'skipped':<13} {'':>5}  (root: {case.root_skip})", flush=True)
                continue
            d = SHARED / f"case{k:03d}"
            d.mkdir()
            try:
                r = run_case(case, d, args.fit_timeout if case.fit else args.timeout)
            except Exception as exc:  # the catalogue's fault (setup, timing), not the CLI's
                skipped.append((case.name, f"not run: {exc}"))
                print(row + f"{'NOT-RUN':<13} {'':>5}  {exc}", flush=True)
                continue
            finally:
                for p in [d, *d.rglob("*")]:
                    if p.is_dir() and not p.is_symlink():
                        os.chmod(p, 0o755)      # so that the cleanup can remove it
            results.append(r)
            rc = "-" if r["rc"] is None else r["rc"]
            print(row + f"{r['outcome']:<13} {rc:>5}  {r['first'][:120]}", flush=True)
    finally:
        if not args.keep_temp:
            shutil.rmtree(SHARED, ignore_errors=True)
    n = {o: sum(r["outcome"] == o for r in results)
         for o in ("clean", "traceback", "silent-wrong", "data-lost", "hang", "misleading")}
    print(f"\ncases: {len(results)}, clean errors: {n['clean']}, tracebacks: {n['traceback']}, "
          f"silent wrong results: {n['silent-wrong']}, data lost: {n['data-lost']}, "
          f"hangs: {n['hang']}, misleading: {n['misleading']}, skipped: {len(skipped)}")
    bad = [r for r in results if r["outcome"] != "clean"]
    print("\nnot clean:" if bad else "")
    for r in bad:
        print(f"  {r['name']}: {r['outcome']}, exit {r['rc']}: {r['detail'][:300]}")
    for name, why in skipped:
        print(f"  skipped {name}: {why}")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
