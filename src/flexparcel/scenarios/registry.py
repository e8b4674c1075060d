"""The scenario registry: name -> factory of a :class:`~flexparcel.scenarios.base.Scenario`.

Built-in scenarios are registered here by ``"module:attribute"`` reference, so looking up
the names imports nothing; a scenario's module is imported when it is first asked for.
Third-party packages add scenarios through the entry-point group ``flexparcel.scenarios``
(``[project.entry-points."flexparcel.scenarios"] my-test = "mypkg.mytest:MyTest"``): the
entry points' names are read on the first lookup, each one loaded when its name is asked
for. A name registered in code wins over an entry point of the same name.

Adding a built-in scenario: one module with its class, plus one line in :data:`BUILTINS`.
"""

from __future__ import annotations

import importlib
import warnings
from collections.abc import Callable
from typing import Any

from flexparcel.scenarios.base import Scenario

__all__ = [
    "ENTRY_POINT_GROUP",
    "BUILTINS",
    "UnknownScenarioError",
    "register_scenario",
    "get_scenario",
    "scenario_names",
]

ENTRY_POINT_GROUP = "flexparcel.scenarios"

ScenarioFactory = Callable[..., Scenario]

BUILTINS: dict[str, str] = {
    "swing": "flexparcel.scenarios.swing:SwingScenario",
    "drop-vertical": "flexparcel.scenarios.drop:vertical_drop",
    "drop-horizontal": "flexparcel.scenarios.drop:horizontal_drop",
    "conveyor": "flexparcel.scenarios.conveyor_scenario:ConveyorScenario",
}
"""Built-in scenarios: name -> ``"module:factory"``."""

# name -> factory, or a "module:attribute" reference / entry point resolved on first use
_FACTORIES: dict[str, Any] = {}
_discovered = False


class UnknownScenarioError(ValueError):
    """A scenario name that nothing registered."""


def register_scenario(name: str, factory: ScenarioFactory | str, *, replace: bool = False) -> None:
    """Register ``factory`` (a callable returning a Scenario, taking the scenario's keyword
    options; or a ``"module:attribute"`` reference to one) as scenario ``name``. A name
    already taken raises ``ValueError`` unless ``replace``."""
    if not isinstance(name, str) or not name.strip():
        raise ValueError(f"a scenario name must be a non-empty string, got {name!r}")
    if name in _FACTORIES and not replace and _FACTORIES[name] is not factory:
        raise ValueError(f"a scenario named {name!r} is already registered")
    if not (callable(factory) or (isinstance(factory, str) and ":" in factory)):
        raise ValueError(f"scenario {name!r}: factory must be callable or 'module:attribute'")
    _FACTORIES[name] = factory


def _discover() -> None:
    """Add the entry points of :data:`ENTRY_POINT_GROUP` (not loaded yet), once."""
    global _discovered
    if _discovered:
        return
    _discovered = True
    from importlib.metadata import entry_points

    for ep in entry_points(group=ENTRY_POINT_GROUP):
        if ep.name in _FACTORIES:
            warnings.warn(
                f"entry point {ep.value!r} of {ENTRY_POINT_GROUP!r} ignored: scenario "
                f"{ep.name!r} is already registered",
                stacklevel=3,
            )
            continue
        _FACTORIES[ep.name] = ep


def _factory(name: str) -> ScenarioFactory:
    """The callable registered as ``name``, importing or loading it on first use."""
    from importlib.metadata import EntryPoint

    target = _FACTORIES[name]
    if isinstance(target, str):
        module, _, attr = target.partition(":")
        target = getattr(importlib.import_module(module), attr)
    elif isinstance(target, EntryPoint):
        try:
            target = target.load()
        except Exception as exc:  # a broken plug-in must not look like an unknown name
            raise ImportError(f"scenario {name!r}: entry point failed to load: {exc}") from exc
    if not callable(target):
        raise TypeError(f"scenario {name!r}: {target!r} is not callable")
    _FACTORIES[name] = target
    return target


def get_scenario(name: str, **options: Any) -> Scenario:
    """A new scenario ``name``, made by its factory with ``options`` (e.g.
    ``get_scenario("drop-vertical", drop_height=0.05)``). An unknown name raises
    :class:`UnknownScenarioError` listing the known ones."""
    _discover()
    if name not in _FACTORIES:
        raise UnknownScenarioError(
            f"unknown scenario {name!r}; known: {', '.join(scenario_names())}"
        )
    scenario = _factory(name)(**options)
    if not isinstance(scenario, Scenario):
        raise TypeError(f"scenario {name!r}: its factory returned {type(scenario).__name__}, "
                        "which lacks the Scenario protocol")  # fmt: skip
    return scenario


def scenario_names() -> list[str]:
    """Registered names: the built-ins first (as in :data:`BUILTINS`), then the others in
    registration order, then entry points."""
    _discover()
    return list(_FACTORIES)


for _name, _ref in BUILTINS.items():
    register_scenario(_name, _ref)
