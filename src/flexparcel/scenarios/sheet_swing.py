"""Sheet swing: a single packaging sheet clamped along one short edge, released horizontal.

The structural-core stand-in for the paper's swing test (section 3.2): a 275 x 200 mm sheet of
the KP/BW packaging material (E = 926 MPa, nu = 0.1, beta = 1.71e-3 s, Table 6), 0.3 mm thick,
40 g, 20 mm of its length clamped, swinging down under gravity for 1.4 s.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from flexparcel.builder import ModelBuilder
from flexparcel.model import mesh
from flexparcel.model.materials import ShellMaterial
from flexparcel.model.model import Model

__all__ = ["SheetSwing", "sheet_swing_model"]


@dataclass(frozen=True)
class SheetSwing:
    """Parameters of the sheet swing case (SI units)."""

    length: float = 0.275
    width: float = 0.200
    thickness: float = 0.3e-3
    mass: float = 0.040
    youngs_modulus: float = 926e6
    poisson_ratio: float = 0.1
    damping_ratio: float = 1.71e-3
    element_size: float = 0.010
    clamped_length: float = 0.020
    t_end: float = 1.4

    @property
    def density(self) -> float:
        """Density [kg/m^3] that gives the sheet its mass."""
        return self.mass / (self.length * self.width * self.thickness)


def sheet_swing_model(case: SheetSwing | None = None) -> tuple[Model, np.ndarray]:
    """Build the model; returns it and the node ids of the free end (x = length).

    The mesh has ``round(length / element_size)`` x ``round(width / element_size)`` quads
    (28 x 20 of 9.8 x 10 mm for the defaults); nodes with x <= clamped_length are clamped.
    """
    c = case or SheetSwing()
    nx = max(1, round(c.length / c.element_size))
    ny = max(1, round(c.width / c.element_size))
    pts, quads = mesh.rectangle(c.length, c.width, nx, ny)
    b = ModelBuilder(gravity=(0.0, 0.0, -9.81))
    mat = ShellMaterial(c.youngs_modulus, c.poisson_ratio, c.density, c.thickness, c.damping_ratio)
    ids = b.add_shell_mesh(pts, quads, material=mat)
    b.clamp(ids[pts[:, 0] <= c.clamped_length + 1e-9])
    return b.finalize(), ids[np.isclose(pts[:, 0], c.length)]
