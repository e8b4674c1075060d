"""Input checks shared by the model's parameter objects (materials, contact laws, scenes)."""

from __future__ import annotations

import math

__all__ = ["finite_number"]


def finite_number(where: str, value: object) -> float:
    """``value`` as a finite float, else ``ValueError`` naming ``where``. Booleans and strings
    are refused: a TOML ``true`` or ``"3"`` in a parameter is a mistake, not a number."""
    if isinstance(value, bool | str | bytes):
        raise ValueError(f"{where} must be a number, got {value!r}")
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{where} must be a number, got {value!r}") from None
    if not math.isfinite(v):
        raise ValueError(f"{where} must be finite, got {value!r}")
    return v
