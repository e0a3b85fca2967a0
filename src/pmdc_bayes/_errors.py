"""Errors raised for user mistakes: one line, naming the file, the place and the fix."""

from __future__ import annotations

from pathlib import Path

__all__ = ["SessionError", "UsageError", "FitFailed", "EXIT_FAILED", "EXIT_USAGE",
           "EXIT_INADEQUATE", "EXIT_INTERNAL"]


class SessionError(ValueError):
    """A session directory or one of its files cannot be used as given.

    The message is one line: ``<file>[:<where>]: <what is wrong>; <how to fix it>``.
    The command line prints it and exits with code 2.
    """

    def __init__(self, path: str | Path | None, message: str, *, where: str | None = None):
        self.path = None if path is None else Path(path)
        self.where = where
        self.message = message
        prefix = "" if path is None else str(path)
        if where:
            prefix = f"{prefix}:{where}" if prefix else where
        text = f"{prefix}: {message}" if prefix else message
        super().__init__(" ".join(text.split()))


class UsageError(ValueError):
    """A command-line option or output location is unusable (exit code 2)."""


class NotApplicable(SessionError):
    """The paper's closed-form method cannot run on this session (it lacks a steady
    current or a step).  A fit seeds itself from the data instead; the closed-form
    command alone reports it as bad input."""


class FitFailed(RuntimeError):
    """The fit cannot go on from its MAP (its curvature is not finite: the model
    overflows near the optimum).  One line; the command line exits with code 1."""


EXIT_FAILED = 1  # the fit or the posterior's gates failed
EXIT_USAGE = 2  # bad input
EXIT_INADEQUATE = 3  # the data reject the model
EXIT_INTERNAL = 4  # a fault of the tool
