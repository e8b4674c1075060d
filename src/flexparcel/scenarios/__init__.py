"""Scenarios: ready-made models and the responses users look at."""

from flexparcel.scenarios.sheet_swing import SheetSwing, sheet_swing_model

__all__ = ["SheetSwing", "sheet_swing_model"]
