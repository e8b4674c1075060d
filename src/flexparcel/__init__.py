"""flexparcel: multi flexible body dynamics of limp consignments in parcel sorting.

The structural core is imported here. The calibration and selection toolkits live in
:mod:`flexparcel.calibration` and :mod:`flexparcel.selection` and are imported on demand.
"""

__version__ = "0.1.0"

from flexparcel.contact.law import ContactLaw
from flexparcel.elements.solid import SolidMaterial
from flexparcel.integrate.dynamic import IntegratorOptions
from flexparcel.integrate.errors import ConvergenceError
from flexparcel.integrate.static import StaticResult, solve_static
from flexparcel.model import mesh
from flexparcel.model.builder import Model, ModelBuilder, State
from flexparcel.model.materials import ShellMaterial
from flexparcel.model.rigid import PrescribedMotion, RoundedBox
from flexparcel.model.schedule import Schedule
from flexparcel.simulate import SimulationResult, simulate

__all__ = [
    "__version__",
    "mesh",
    "ModelBuilder",
    "Model",
    "State",
    "ShellMaterial",
    "SolidMaterial",
    "RoundedBox",
    "PrescribedMotion",
    "ContactLaw",
    "Schedule",
    "solve_static",
    "StaticResult",
    "simulate",
    "SimulationResult",
    "IntegratorOptions",
    "ConvergenceError",
]
