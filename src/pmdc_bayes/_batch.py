"""A lot of motors in one ``pmdc-bayes fit``: several session directories (or folders
of them) fitted in turn in one process, so that sessions of a shape already seen reuse
its compiled programs; one line per motor, and a table of the lot (``lot.csv`` in the
``--out`` folder).
"""

from __future__ import annotations

import csv
import errno
import io
import os
from dataclasses import dataclass
from pathlib import Path

from ._errors import UsageError
from .io.bundled import passed_over, session_path
from .rundir import check_replaceable, check_writable, is_run_dir

__all__ = ["LotEntry", "expand_sessions", "bundled_note", "lot_outs", "claim_lot", "is_lot_dir",
           "clear_lot_files", "resolved", "lot_table", "write_lot", "STATUS", "LOT_MARKER",
           "LOT_FILES"]

STATUS = {0: "ok", 1: "failed gates", 2: "bad input", 3: "model inadequate"}
_PARAMS = ("Ra", "La", "K", "B", "J", "Tc")
LOT_MARKER = ".pmdc-bayes-lot"  # in a folder this tool claimed for a lot
LOT_FILES = ("lot.csv", "lot.json", "population.nc", "lot.png")  # a lot's own files


@dataclass
class LotEntry:
    """One session of a lot: its directory, exit status, run directory and summary
    (None when it could not be fitted), and the one-line error when there was one."""

    session: Path
    status: int
    run: Path | None = None
    summary: dict | None = None
    error: str = ""


def expand_sessions(args, *, note=None) -> list[Path]:
    """The session directories named: each argument a session directory, a bundled
    session's name, or a folder whose subfolders hold sessions (in name order); the
    bundled default for none.  A run directory is neither a session nor a folder of them.
    ``note(text)`` hears of each bundled session used in place of a local directory of
    its name that holds no session."""
    if not args:
        return [session_path(None)]
    found = []
    for arg in args:
        p = session_path(arg)
        if p.name == "session.toml" and p.is_file():  # the session is its folder
            p = p.parent
        if note is not None and (local := passed_over(arg)) is not None:
            note(bundled_note(arg, local, p))
        if is_run_dir(p):
            raise UsageError(f"{p}: a run directory written by 'pmdc-bayes fit', not a "
                             "session; pass the session directory it was fitted from")
        if p.is_dir() and not (p / "session.toml").exists():
            subs = sorted(d for d in p.iterdir() if (d / "session.toml").is_file())
            if not subs:
                raise UsageError(f"{p}: neither a session (no session.toml) nor a folder of "
                                 "sessions; pass session directories")
            found += subs
        else:
            found.append(p)
    resolved_paths = [resolved(p) for p in found]
    twice = next((p for k, p in enumerate(resolved_paths) if p in resolved_paths[:k]), None)
    if twice is not None:
        raise UsageError(f"{twice}: named twice; give each session once")
    return found


def bundled_note(name: str, local: Path, used: Path) -> str:
    """One line saying that the bundled session ``name`` (at ``used``) is used, not the
    local ``local`` of the same name, and why."""
    what = ("a run directory" if is_run_dir(local) else "a directory without session.toml"
            if local.is_dir() else "not a directory")
    how = f"; write ./{name} for the local one" if what.endswith("session.toml") else ""
    return (f"using the bundled session '{name}' ({used}): ./{name} here is {what}, "
            f"not a session{how}")


def lot_outs(paths: list[Path], out: Path | None, force: bool) -> list[Path | None]:
    """Each session's run directory under ``out`` (named after the session, ``-2``,
    ``-3`` ... for sessions of the same name, never a name of the lot's own files);
    None each without ``out`` (the default ``reports/<session>-<time>``).  Refuses,
    before any fit, an ``out`` that cannot be written, that is a session, holds one of
    the lot's or lies inside any, that holds files of the user's (a folder other than an
    earlier lot), or an earlier lot or any run directory it would replace unless
    ``force``."""
    if out is None:
        return [None] * len(paths)
    if out.is_symlink() and not out.exists():
        raise UsageError(f"{out}: a link to nothing; choose another --out")
    if out.exists() and not out.is_dir():
        raise UsageError(f"{out}: --out is a file; with several sessions --out is the "
                         "folder that gets one run per session")
    check_writable(out)
    where = resolved(out)
    inside = next((a for a in where.parents if (a / "session.toml").is_file()), None)
    if inside is not None or (where / "session.toml").is_file():
        raise UsageError(f"{out}: --out {'lies inside' if inside else 'is'} the session "
                         f"{inside or where}; choose a folder apart from the sessions")
    for p in paths:
        if where in resolved(p).parents:
            raise UsageError(f"{out}: --out holds the session {p}; choose a folder apart "
                             "from the sessions")
    if out.is_dir() and {e.name for e in out.iterdir()} - {LOT_MARKER}:
        if not is_lot_dir(out):
            raise UsageError(f"{out}: holds files that are not a lot written by pmdc-bayes; "
                             "choose a new or empty folder for --out")
        if not force:
            raise UsageError(f"{out}: holds an earlier lot; pass --force to replace its runs "
                             "and table, or choose another --out")
    taken = {n.casefold() for n in (*LOT_FILES, LOT_MARKER)}
    outs = []
    for p in paths:
        name = resolved(p).name
        k, unique = 1, name
        while unique.casefold() in taken:
            k += 1
            unique = f"{name}-{k}"
        taken.add(unique.casefold())
        outs.append(out / unique)
    for o in outs:
        check_replaceable(o, force)
    return outs


def resolved(path: Path) -> Path:
    """``path`` with its links followed; a link that leads back to itself, on the way to
    it or at it, is the user's to mend (:class:`UsageError`)."""
    for p in (path, *path.parents):
        try:
            os.stat(p)
        except FileNotFoundError:
            continue
        except OSError as exc:
            if exc.errno == errno.ELOOP:
                raise UsageError(f"{path}: {p} is a link that leads back to itself; give "
                                 "the folder itself") from None
    try:
        return path.resolve()
    except (RuntimeError, OSError):  # a loop Python meets before the file system does
        raise UsageError(f"{path}: a link that leads back to itself; give the folder "
                         "itself") from None


def is_lot_dir(path: Path) -> bool:
    """Whether ``path`` is a folder of a lot this tool wrote: its marker file, or (a lot
    written before the marker) a ``lot.csv`` beside nothing but the lot's own files and
    run directories."""
    if not path.is_dir():
        return False
    if (path / LOT_MARKER).is_file():
        return True
    try:
        with (path / "lot.csv").open(encoding="utf-8") as f:
            header = f.readline()
    except (OSError, UnicodeDecodeError):
        return False
    ours = header.startswith(("session,status,exit_code,", "motor,session,status,"))
    return ours and all(e.name in LOT_FILES or is_run_dir(e) for e in path.iterdir())


def claim_lot(out: Path | None) -> None:
    """Make ``out`` (checked by :func:`lot_outs`) a lot's folder: created, marked as this
    tool's, so that a later ``--force`` may replace what it holds and nothing else."""
    if out is None:
        return
    out.mkdir(parents=True, exist_ok=True)
    (out / LOT_MARKER).write_text("a lot's folder written by pmdc-bayes\n", encoding="utf-8")


def clear_lot_files(out: Path, keep) -> None:
    """Remove from the lot folder ``out`` the lot's own files not in ``keep`` (an earlier
    lot's, which the one being written does not replace: its population, when this one
    has none or is a plain ``fit`` of several sessions)."""
    for name in set(LOT_FILES) - set(keep):
        (out / name).unlink(missing_ok=True)


def _row(entry: LotEntry) -> dict:
    row = {"session": str(entry.session), "status": STATUS.get(entry.status, "error"),
           "exit_code": entry.status, "run": str(entry.run or ""), "error": entry.error}
    params = (entry.summary or {}).get("parameters", {})
    for name in _PARAMS:
        p = params.get(name, {})
        row[name] = p.get("mean", p.get("map", ""))
        row[f"{name}_sd"] = p.get("sd", p.get("map_sd", ""))
    return row


def lot_table(entries: list[LotEntry]) -> str:
    """The lot as text: one line per motor, its status and where its run is."""
    width = max(7, *(len(e.session.name) for e in entries))
    lines = [f"{'session':<{width}}  {'status':<17} run or error"]
    for e in entries:
        lines.append(f"{e.session.name:<{width}}  {STATUS.get(e.status, 'error'):<17} "
                     f"{e.run if e.run else e.error}")
    ok = sum(e.status == 0 for e in entries)
    lines.append(f"{ok} of {len(entries)} motors ok")
    return "\n".join(lines)


def write_lot(out: Path, entries: list[LotEntry]) -> Path:
    """``out/lot.csv``: per motor its status, run directory and each parameter's value
    and sd in SI (posterior mean and sd, the MAP and its Laplace sd without a
    posterior); written whole (a temporary file renamed into place)."""
    out.mkdir(parents=True, exist_ok=True)
    clear_lot_files(out, keep=("lot.csv",))
    rows = [_row(e) for e in entries]
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=list(rows[0]), lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    path = out / "lot.csv"
    tmp = out / f".lot.csv.{os.getpid()}"
    tmp.write_text(buf.getvalue(), encoding="utf-8")
    os.replace(tmp, path)
    return path
