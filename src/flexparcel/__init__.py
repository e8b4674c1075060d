"""flexparcel: multi flexible body dynamics of limp consignments in parcel sorting.

The public names of the structural core (``fp.ModelBuilder``, ``fp.simulate``, ...) are loaded
lazily, on first access (PEP 562), so importing :mod:`flexparcel.calibration` or
:mod:`flexparcel.selection` does not load the finite-element stack (numba kernels, sparse
assembly, contact). Quantities are SI throughout (m, kg, s, N, Pa) unless a name says otherwise.
"""

from __future__ import annotations

import importlib
import sys
import types

from flexparcel._version import __version__

# Public name -> module that defines it: the one place to update when a definition moves. The
# name is looked up in that module; a module without it that is itself called so ("mesh") is the
# value.
_LAZY: dict[str, str] = {
    "mesh": "flexparcel.model.mesh",
    "ModelBuilder": "flexparcel.builder",
    "Model": "flexparcel.model.model",
    "State": "flexparcel.model.model",
    "ShellMaterial": "flexparcel.model.materials",
    "SolidMaterial": "flexparcel.elements.solid",
    "RoundedBox": "flexparcel.model.rigid",
    "PrescribedMotion": "flexparcel.model.rigid",
    "ContactLaw": "flexparcel.contact.law",
    "Schedule": "flexparcel.model.schedule",
    "solve_static": "flexparcel.integrate.static",
    "StaticResult": "flexparcel.integrate.static",
    "simulate": "flexparcel.simulate",
    "SimulationResult": "flexparcel.simulate",
    "IntegratorOptions": "flexparcel.integrate.dynamic",
    "ConvergenceError": "flexparcel.integrate.errors",
}

__all__ = ["__version__", *_LAZY]


def _resolve(name: str):
    module = importlib.import_module(_LAZY[name])
    if hasattr(module, name):
        return getattr(module, name)
    if module.__name__.rsplit(".", 1)[-1] == name:
        return module
    raise ImportError(f"{module.__name__} defines no {name!r} (flexparcel._LAZY is stale)")


def __getattr__(name: str):
    """Import the public name ``name`` from its module on first use and keep it here."""
    if name not in _LAZY:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = _resolve(name)
    setattr(sys.modules[__name__], name, value)
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))


class _Package(types.ModuleType):
    """The package module. Importing a submodule binds it as an attribute of its package; where a
    public name is also a submodule (``flexparcel.simulate``), the public name (the function)
    keeps that attribute, as it did when the names were imported eagerly."""

    def __setattr__(self, name: str, value) -> None:
        if (
            isinstance(value, types.ModuleType)
            and value.__name__ == f"{__name__}.{name}"
            and _LAZY.get(name) == value.__name__
            and hasattr(value, name)
        ):
            value = getattr(value, name)
        super().__setattr__(name, value)


sys.modules[__name__].__class__ = _Package
