"""Air drag on shell surfaces: the pressure drag of still air on each triangle, quadratic in
its normal velocity.

A limp consignment is light for its area (KP/BW: 130 g/m^2 of packaging, about 1.9 kg/m^2 in
all), so air resists it where it moves broadside: the swing test's free end sweeps 0.08 m^2
at up to 2 m/s. The paper's RecurDyn model has no air; this group lets the model have it, as
an option (``drag_coefficient = 0`` is the paper's model).

Model (quasi-steady flat-plate drag, e.g. Hoerner 1965, *Fluid-Dynamic Drag*, ch. 3): a
triangle with area vector ``a = (x2 - x1) x (x3 - x1) / 2`` (|a| its area A, a / A its normal
n) moving at its centroid velocity ``v`` (the mean of its nodes') feels

    f = -1/2 rho C_d A (n . v) |n . v| n,

shared equally by its three nodes. Only the normal velocity counts (skin friction along a
smooth film is two orders smaller) and the air does not move (no added mass, no wake memory:
a flapping film's added mass and vortex shedding are not modelled). A closed surface (both
layers of an envelope) gets the drag on each layer, i.e. twice a flat plate's; give such a
surface half the plate's coefficient, or only its outer layer.

As an element group the drag is an internal force ``g = -f`` (the solver's convention):
``C = dg/dv = rho C_d A |n . v| n n^T / 9`` per node pair (positive semi-definite) and
``K = dg/dx`` from the area vector's change (:func:`_drag_kernel`). Both are exact and are
checked against finite differences (tests/test_air_drag.py).
"""

from __future__ import annotations

import numba as nb
import numpy as np

from flexparcel.elements.rotations import skew
from flexparcel.elements.solid import scatter_forces
from flexparcel.model.interfaces import TranslationalElementGroup

__all__ = ["AirDrag", "AIR_DENSITY", "FLAT_PLATE_DRAG_COEFFICIENT", "check_drag_coefficient"]

AIR_DENSITY = 1.204
"""Density of dry air at 20 degC and 101.325 kPa [kg/m^3]."""

FLAT_PLATE_DRAG_COEFFICIENT = 1.17
"""Drag coefficient of a square flat plate normal to the flow (Hoerner 1965, ch. 3)."""


MAX_DRAG_COEFFICIENT = 5.0
"""Largest accepted C_d: bluff bodies stay below about 2 (Hoerner 1965), 5 catches unit
mistakes."""


def check_drag_coefficient(value: float, what: str) -> float:
    """``value`` as a drag coefficient in [0, 5], or ``ValueError`` naming ``what``."""
    if not (np.isfinite(value) and 0.0 <= value <= MAX_DRAG_COEFFICIENT):
        raise ValueError(
            f"{what} must be in [0, {MAX_DRAG_COEFFICIENT:g}] (a flat plate: "
            f"{FLAT_PLATE_DRAG_COEFFICIENT}), got {value!r}"
        )
    return float(value)


@nb.njit(cache=True)
def _drag_kernel(tri, pos, vel, k_tri, fe, ke, ce, tangent):
    """Per triangle ``e``: internal drag force ``fe[e]`` (9,) on its nodes and, with
    ``tangent``, ``ke[e] = dg/dx`` and ``ce[e] = dg/dv`` (9, 9). ``k_tri[e]``: rho C_d / 2
    times the triangle's weight."""
    for e in range(tri.shape[0]):
        k_air = k_tri[e]
        i, j, k = tri[e, 0], tri[e, 1], tri[e, 2]
        e2 = pos[j] - pos[i]
        e3 = pos[k] - pos[i]
        a = 0.5 * np.cross(e2, e3)
        area = np.sqrt(a @ a)
        v = (vel[i] + vel[j] + vel[k]) / 3.0
        s = (a @ v) / area  # normal velocity n . v
        # g = k s |s| a = k A (n . v) |n . v| n on the triangle, a third on each node
        g = k_air * s * abs(s) * a
        for n in range(3):
            fe[e, 3 * n : 3 * n + 3] = g / 3.0
        if not tangent:
            continue
        # ds/dv = a / A, ds/da = (v - s a / A) / A
        dg_dv = (2.0 * k_air * abs(s) / area) * np.outer(a, a)
        dg_da = k_air * s * abs(s) * np.eye(3) + (2.0 * k_air * abs(s) / area) * np.outer(
            a, v - s * a / area
        )
        # da/dx of the three nodes: a = (x2 - x1) x (x3 - x1) / 2
        da = (0.5 * (skew(e3) - skew(e2)), -0.5 * skew(e3), 0.5 * skew(e2))
        for r in range(3):
            for c in range(3):
                ke[e, 3 * r : 3 * r + 3, 3 * c : 3 * c + 3] = (dg_da @ da[c]) / 3.0
                ce[e, 3 * r : 3 * r + 3, 3 * c : 3 * c + 3] = dg_dv / 9.0


class AirDrag(TranslationalElementGroup):
    """Quadratic pressure drag of still air on triangles (see the module docstring).

    ``triangles`` (m, 3): node ids of the surface, either orientation (the force does not
    depend on it); ``weights`` (m,): each triangle's share, e.g. 1/2 for the four triangles
    of both diagonals of a quad (:func:`flexparcel.model.mesh.quads_to_triangles`); default 1;
    ``drag_coefficient`` C_d [-] >= 0; ``air_density`` rho [kg/m^3] > 0. Adds no mass and no
    stiffness at rest.
    """

    kind = "air"

    def __init__(
        self,
        triangles: np.ndarray,
        weights: np.ndarray | None = None,
        drag_coefficient: float = FLAT_PLATE_DRAG_COEFFICIENT,
        air_density: float = AIR_DENSITY,
    ) -> None:
        tri = np.asarray(triangles, dtype=np.int64)
        if tri.ndim != 2 or tri.shape[1] != 3 or len(tri) == 0:
            raise ValueError(f"AirDrag.triangles must have shape (m, 3), m >= 1, got {tri.shape}")
        check_drag_coefficient(drag_coefficient, "AirDrag.drag_coefficient")
        if not (np.isfinite(air_density) and air_density > 0.0):
            raise ValueError(f"AirDrag.air_density must be > 0 kg/m^3, got {air_density!r}")
        w = np.ones(len(tri)) if weights is None else np.asarray(weights, dtype=float)
        if w.shape != (len(tri),) or not np.all(np.isfinite(w) & (w >= 0.0)):
            raise ValueError(f"AirDrag.weights must be {len(tri)} numbers >= 0, one per triangle")
        self.weights = w
        self.cells = np.ascontiguousarray(tri)
        self.drag_coefficient = float(drag_coefficient)
        self.air_density = float(air_density)
        self.emap = np.zeros((len(tri), 9, 9), np.int64)
        # rho C_d / 2 per triangle, weighted: fixed for the group's life
        self._k_tri = 0.5 * self.air_density * self.drag_coefficient * w

    @property
    def triangles(self) -> np.ndarray:
        """Node ids of the triangles, shape (m, 3)."""
        return self.cells

    def lumped_mass(self, node_count: int) -> np.ndarray:
        return np.zeros((node_count, 6))

    def fingerprint_arrays(self) -> list[np.ndarray]:
        coefficients = np.array([self.drag_coefficient, self.air_density])
        return [*super().fingerprint_arrays(), coefficients, self.weights]

    def _evaluate(self, positions, velocities, out, data_k, data_c) -> float:
        m = len(self.cells)
        fe = np.empty((m, 9))
        tangent = data_k is not None
        ke = np.zeros((m, 9, 9) if tangent else (1, 9, 9))
        ce = np.zeros_like(ke)
        pos = np.ascontiguousarray(positions)
        vel = np.ascontiguousarray(velocities[:, :3])
        _drag_kernel(self.cells, pos, vel, self._k_tri, fe, ke, ce, tangent)
        f3 = np.zeros((out.shape[0], 3))
        scatter_forces(self.cells, fe, f3)
        out[:, :3] += f3
        if tangent:
            np.add.at(data_k, self.emap.ravel(), ke.ravel())
            np.add.at(data_c, self.emap.ravel(), ce.ravel())
        return 0.0  # drag stores no energy
