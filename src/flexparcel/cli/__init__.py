"""The ``flexparcel`` command.

Each sub-command lives in its own module of this package and exposes ``register(subparsers)``,
which adds its parser and sets ``func`` (a callable taking the parsed ``argparse.Namespace`` and
returning an exit code). Heavy optional dependencies are imported inside those callables only, so
``flexparcel --help`` stays fast and works with the core install.

Errors. Every expected failure ends with one line ``flexparcel COMMAND: error: ...`` naming
the file and what is wrong, and exit status 2: bad options and values (``ValueError``),
unreadable or damaged files (:class:`flexparcel.io.FileFormatError`, malformed JSON or TOML),
missing files and other operating-system errors (``OSError``, with the path), a missing key,
a missing optional dependency. A run that fails on the way (an assembly that does not settle,
a time step that does not converge) exits with 1, an interrupted one with 130. What happens to
the ``--out`` folder of a failed command: :mod:`flexparcel.cli.outdir`.
"""

from __future__ import annotations

import argparse
import importlib
import sys

__all__ = ["main", "build_parser"]

# Commands that run numba kernels: the first of them on a cold cache says it compiles.
_COMPILING_COMMANDS = frozenset({"demo", "assemble", "run", "bench", "verify", "calibrate"})

# Sub-command modules, in the order they appear in --help.
_COMMAND_MODULES = (
    "flexparcel.cli.demo_cmd",
    "flexparcel.cli.assemble_cmd",
    "flexparcel.cli.run_cmd",
    "flexparcel.cli.view_cmd",
    "flexparcel.cli.bench_cmd",
    "flexparcel.cli.verify_cmd",
    "flexparcel.cli.calibrate_cmd",
    "flexparcel.cli.select_cmd",
)


def build_parser() -> argparse.ArgumentParser:
    from flexparcel._version import __version__

    parser = argparse.ArgumentParser(
        prog="flexparcel",
        description="Multi flexible body dynamics of limp consignments in parcel sorting.",
    )
    parser.add_argument("--version", action="version", version=f"flexparcel {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in _COMMAND_MODULES:
        try:
            module = importlib.import_module(name)
        except ModuleNotFoundError as exc:  # a sub-command not (yet) shipped in this checkout
            if exc.name == name:
                continue
            raise
        module.register(sub)
    return parser


def describe_error(exc: BaseException) -> str:
    """One line for an expected failure: the file and what is wrong with it."""
    import json
    import tomllib

    if isinstance(exc, OSError):
        what = exc.strerror or str(exc) or type(exc).__name__
        if exc.filename is None:
            return str(exc) or what
        names = f"{exc.filename}" + (f" -> {exc.filename2}" if exc.filename2 else "")
        if isinstance(exc, FileNotFoundError) and str(exc).startswith(f"{exc.filename}"):
            return str(exc)
        return f"{names}: {what}"
    if isinstance(exc, json.JSONDecodeError):
        return f"not valid JSON: {exc}"
    if isinstance(exc, tomllib.TOMLDecodeError):
        return f"not valid TOML: {exc}"
    if isinstance(exc, KeyError):
        return f"missing key {exc}"
    if isinstance(exc, ModuleNotFoundError):
        return (
            f"this needs the package {exc.name!r}, which is not installed; "
            "pip install 'flexparcel[all]' (or the extra named in the README's Install section)"
        )
    return str(exc) or type(exc).__name__


def _out_folder(args: argparse.Namespace, argv: list[str] | None):
    """The :class:`~flexparcel.cli.outdir.OutputFolder` of a command whose ``--out`` is a
    folder (those set ``out_is_dir``), else None."""
    from pathlib import Path

    from flexparcel.cli.outdir import OutputFolder

    out = getattr(args, "out", None)
    if not getattr(args, "out_is_dir", False) or out is None:
        return None
    return OutputFolder(Path(out), args.command, argv)


def _plain_warnings(command: str) -> None:
    """Warnings as one line each, ``flexparcel CMD: warning: message``, not Python's
    file-and-source-line form."""
    import warnings

    def show(message, category, filename, lineno, file=None, line=None):
        print(f"flexparcel {command}: warning: {message}", file=file or sys.stderr)

    warnings.showwarning = show


def main(argv: list[str] | None = None) -> int:
    from flexparcel.io.results import FileFormatError

    parser = build_parser()
    args = parser.parse_args(argv)
    if getattr(args, "func", None) is None:
        parser.print_help()
        return 0
    name = args.command
    _plain_warnings(name)
    folder = None
    error = None
    try:
        folder = _out_folder(args, argv)
        if name in _COMPILING_COMMANDS and not getattr(args, "preview", None):
            from flexparcel.cli.progress import announce_compilation

            announce_compilation()
        status = int(args.func(args) or 0)
    except KeyboardInterrupt:
        error, status = "interrupted", 130
    except (FileFormatError, ValueError, OSError, KeyError, ModuleNotFoundError) as exc:
        error, status = describe_error(exc), 2
    if error is not None:
        print(f"flexparcel {name}: error: {error}", file=sys.stderr)
    if folder is not None:
        if status == 0:
            folder.succeeded()
        else:
            done = folder.failed(status, None if error is None else f"error: {error}")
            if done:
                print(f"flexparcel {name}: {done}", file=sys.stderr)
    return status


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
