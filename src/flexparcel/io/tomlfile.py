"""Reading the TOML input files (consignments, scenes, friction tables): data, never code."""

from __future__ import annotations

import tomllib
from pathlib import Path

__all__ = ["read_toml"]


def read_toml(path: str | Path, error: type[Exception], what: str) -> dict:
    """The parsed TOML document at ``path``.

    Raises ``FileNotFoundError`` ("``what`` not found: path") for a missing file, and
    ``error`` with a message starting with the path for malformed TOML or a file that is not
    UTF-8 text, so every reader reports bad files the same way.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{what} not found: {path}")
    try:
        with path.open("rb") as fh:
            return tomllib.load(fh)
    except tomllib.TOMLDecodeError as exc:
        raise error(f"{path}: not valid TOML: {exc}") from None
    except UnicodeDecodeError as exc:
        raise error(f"{path}: not a UTF-8 text file ({exc})") from None
