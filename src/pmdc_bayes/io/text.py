"""Read a user's text file whole, with one-line errors for every way it can fail.

Files saved by spreadsheets and editors arrive as UTF-8 (with or without a byte-order
mark), UTF-16 (Excel's "Unicode text", always with a mark) or a legacy 8-bit code page;
paths can name a directory, a dangling or looping link, or an unreadable file.  Each
case becomes a :class:`SessionError` naming the file and the fix.
"""

from __future__ import annotations

import codecs
import errno
import os
from pathlib import Path

from .._errors import SessionError

__all__ = ["MAX_BYTES", "read_text"]

MAX_BYTES = 200 * 1024 * 1024
"""Largest file read (200 MB, about six million rows of a three-column trace)."""

_CONTROL = [bytes([c]) for c in (*range(9), 11, *range(14, 32), 127)]  # not in text
_BOMS = ((codecs.BOM_UTF8, "utf-8-sig"), (codecs.BOM_UTF16_LE, "utf-16"),
         (codecs.BOM_UTF16_BE, "utf-16"))


def _raw(path: Path, what: str) -> bytes:
    try:
        size = path.stat().st_size
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            raise SessionError(path, "a symbolic link that points back to itself; point it "
                               f"at the {what} or replace it by the file") from None
        if exc.errno == errno.EACCES:
            raise SessionError(path, "permission denied on the way to the file; make the "
                               "directory readable") from None
        if path.is_symlink():
            raise SessionError(path, f"a symbolic link to {os.readlink(path)}, which does not "
                               f"exist; point it at the {what} or replace it by the file") \
                from None
        raise SessionError(path, f"{what} not found; check the name (it is relative to the "
                           "session directory) or add the file") from None
    if path.is_dir():
        raise SessionError(path, f"a directory, not a file; name the {what} itself")
    if size > MAX_BYTES:
        raise SessionError(path, f"the file is {size / 2**20:.3g} MB, more than pmdc-bayes "
                           f"reads ({MAX_BYTES // 2**20} MB); decimate the log or cut it to "
                           "the tests you fit")
    try:
        return path.read_bytes()
    except PermissionError:
        raise SessionError(path, "permission denied; make the file readable (chmod +r)") \
            from None
    except OSError as exc:
        raise SessionError(path, f"cannot be read ({exc.strerror}); copy it to a readable "
                           "place") from None


def _legacy_bytes(exc: UnicodeDecodeError):
    """Bytes that are not UTF-8 read as Windows-1252 (Latin-1 where it has no letter)."""
    bad = exc.object[exc.start:exc.end]
    return "".join(bytes([b]).decode("cp1252", errors="ignore") or chr(b) for b in bad), exc.end


_LEGACY = "pmdc_bayes_windows_1252"
codecs.register_error(_LEGACY, _legacy_bytes)


def read_text(path: Path, what: str = "file", *, legacy: bool = False) -> str:
    """The text of ``path``: UTF-8, or UTF-8/UTF-16 with a byte-order mark; with
    ``legacy``, the bytes of a file that are not UTF-8 are read as Windows-1252 (Latin-1
    for the bytes that code leaves undefined), as older Windows programs write text.

    ``what`` names the file in messages ("CSV file", "session.toml").  Newlines are
    kept as written (the caller's parser handles them).
    """
    path = Path(path)
    data = _raw(path, what)
    encoding = next((enc for bom, enc in _BOMS if data.startswith(bom)), "utf-8")
    if encoding.startswith("utf-8"):
        data = data.rstrip(b"\0")  # a logger's card pads the file with NULs
    head = data[:4096]
    if encoding == "utf-8" and sum(head.count(c) for c in _CONTROL) > 0.05 * len(head):
        raise SessionError(path, f"a binary file, not text; export the {what} as text "
                           "(UTF-8 CSV)")
    try:
        return data.decode(encoding)
    except UnicodeDecodeError as exc:
        if legacy and encoding == "utf-8":
            return data.decode("utf-8", errors=_LEGACY)
        line = data[:exc.start].count(b"\n") + 1
        bad = data[exc.start:exc.start + 1].hex()
        raise SessionError(
            path, f"not {encoding.upper().replace('-SIG', '')} text (byte 0x{bad}, perhaps "
            f"Latin-1 or Windows-1252); save the {what} as UTF-8", where=f"line {line}",
        ) from None
