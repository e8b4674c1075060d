"""Scenarios: ready-made models and the responses users look at.

Every scenario follows one protocol (:mod:`flexparcel.scenarios.base`) and is found by name in
:mod:`flexparcel.scenarios.registry` (``swing``, ``drop-vertical``, ``drop-horizontal``,
``conveyor``, and third-party ones through the ``flexparcel.scenarios`` entry points). The
names below load lazily, so that importing the registry or the protocol loads no model code.
"""

from __future__ import annotations

from flexparcel._lazy import lazy_exports

__all__ = [
    "Parameter",
    "Response",
    "Scenario",
    "ScenarioResult",
    "get_scenario",
    "register_scenario",
    "scenario_names",
    "SheetSwing",
    "sheet_swing_model",
]

_LAZY = {
    "Parameter": "flexparcel.scenarios.base",
    "Response": "flexparcel.scenarios.base",
    "Scenario": "flexparcel.scenarios.base",
    "ScenarioResult": "flexparcel.scenarios.base",
    "get_scenario": "flexparcel.scenarios.registry",
    "register_scenario": "flexparcel.scenarios.registry",
    "scenario_names": "flexparcel.scenarios.registry",
    "SheetSwing": "flexparcel.scenarios.sheet_swing",
    "sheet_swing_model": "flexparcel.scenarios.sheet_swing",
}


__getattr__, __dir__ = lazy_exports(__name__, _LAZY, globals())
