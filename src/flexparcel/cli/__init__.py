"""The ``flexparcel`` command.

Each sub-command lives in its own module of this package and exposes ``register(subparsers)``,
which adds its parser and sets ``func`` (a callable taking the parsed ``argparse.Namespace`` and
returning an exit code). Heavy optional dependencies are imported inside those callables only, so
``flexparcel --help`` stays fast and works with the core install.
"""

from __future__ import annotations

import argparse
import importlib
import sys

__all__ = ["main", "build_parser"]

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


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if getattr(args, "func", None) is None:
        parser.print_help()
        return 0
    try:
        return int(args.func(args) or 0)
    except (ValueError, FileNotFoundError) as exc:
        print(f"flexparcel {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
