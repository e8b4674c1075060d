"""The output folder of a command (``--out DIR``) when the command fails.

The rule (documented in docs/bad-input.md):

* ``--out`` naming an existing file (not a folder) is refused before anything runs.
* A failed run that **created** the folder and left no file in it removes the folder (and the
  empty sub-folders it made), so a typo or a bad input leaves nothing behind.
* A failed run that **wrote** files into the folder (a partial run: an unsettled assembly's
  last state, a conveyor checkpoint to resume from, the tests that did finish) keeps them and
  writes ``FAILED.txt`` there: the command, the exit status and the error. The next run that
  succeeds in that folder removes ``FAILED.txt``.
* A failed run that wrote nothing into a folder that existed before leaves it untouched.

Commands report a failure they handle themselves (exit status 1) with :func:`report_failure`,
so that its message goes to ``FAILED.txt`` too.
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

__all__ = ["FAILED_FILE", "OutputFolder", "report_failure", "check_out_is_folder"]

FAILED_FILE = "FAILED.txt"

_messages: list[str] = []


def report_failure(message: str) -> None:
    """Print ``message`` on stderr and keep it for the output folder's ``FAILED.txt``."""
    print(message, file=sys.stderr)
    _messages.append(message)


def check_out_is_folder(out: Path, option: str = "--out") -> None:
    """``ValueError`` when ``out`` exists and is not a folder."""
    if out.exists() and not out.is_dir():
        raise ValueError(
            f"{option} {out}: is an existing file, not a folder; give a folder name (it is "
            "created), or remove or rename the file"
        )


def _files_since(folder: Path, start: float) -> list[Path]:
    """Files under ``folder`` modified at or after ``start`` (wall clock)."""
    found = []
    for root, _dirs, files in os.walk(folder):
        for name in files:
            p = Path(root) / name
            try:
                if p.stat().st_mtime >= start:
                    found.append(p)
            except OSError:
                continue
    return found


def _has_files(folder: Path) -> bool:
    return any(files for _root, _dirs, files in os.walk(folder))


def _remove_empty_tree(folder: Path) -> None:
    """Remove ``folder`` and its sub-folders, which hold no file (rmdir only: a file that
    appeared meanwhile stops it)."""
    for root, dirs, _files in os.walk(folder, topdown=False):
        for d in dirs:
            try:
                os.rmdir(Path(root) / d)
            except OSError:
                pass
    try:
        os.rmdir(folder)
    except OSError:
        pass


class OutputFolder:
    """Tracks the ``--out`` folder of one command: whether it existed, and what the command
    wrote into it, to apply the module's rule when the command ends."""

    def __init__(self, out: Path, command: str, argv: list[str] | None = None) -> None:
        self.out = Path(out)
        self.command = command
        self.argv = list(sys.argv[1:] if argv is None else argv)
        check_out_is_folder(self.out)
        self.existed = self.out.exists()
        # file times have a coarse resolution on some file systems: a margin of 1 s
        self.start = time.time() - 1.0
        _messages.clear()

    def succeeded(self) -> None:
        """The command succeeded: remove a ``FAILED.txt`` of an earlier run."""
        stale = self.out / FAILED_FILE
        if stale.is_file():
            stale.unlink()

    def failed(self, status: int, error: str | None = None) -> str:
        """Apply the rule to a failed command; returns what was done (for the user)."""
        if not self.out.is_dir():
            return ""
        if not self.existed and not _has_files(self.out):
            _remove_empty_tree(self.out)
            return ""  # nothing to tell: the folder is gone as if never made
        written = [p for p in _files_since(self.out, self.start) if p.name != FAILED_FILE]
        if not written:
            return ""
        from flexparcel.io.atomic import write_atomic

        lines = [
            f"flexparcel {' '.join(self.argv)}",
            f"failed with exit status {status}:",
            *(_messages or []),
            *([error] if error else []),
            "",
            "The other files in this folder are what the run wrote before it failed.",
            "",
        ]
        write_atomic(self.out / FAILED_FILE, "\n".join(lines))
        return f"partial results kept in {self.out}; the error is in {self.out / FAILED_FILE}"
