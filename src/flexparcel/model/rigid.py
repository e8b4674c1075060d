"""Rigid shapes: cuboids with rounded edges (sphere-swept boxes) and their mass properties.

A rounded box of outer size ``a x b x c`` and edge radius ``r`` is the Minkowski sum of an inner
box ``(a-2r) x (b-2r) x (c-2r)`` and a sphere of radius ``r``: its surface is at distance ``r``
from the inner box, so contact against it is contact against the inner box inflated by ``r``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from flexparcel.model.schedule import Schedule

__all__ = ["RoundedBox", "PrescribedMotion"]


def _positive(owner, name, v):
    v = float(v)
    if not (math.isfinite(v) and v > 0):
        raise ValueError(f"{owner}.{name} must be > 0, got {v!r}")
    return v


@dataclass(frozen=True)
class RoundedBox:
    """Cuboid with rounded edges and corners, body frame at its centre, axes along its edges.

    Attributes: ``length``, ``width``, ``height`` [m] (outer, along body x, y, z);
    ``edge_radius`` [m] in [0, min/2]; exactly one of ``density`` [kg/m^3] or ``mass`` [kg].
    """

    length: float
    width: float
    height: float
    edge_radius: float = 0.0
    density: float | None = None
    mass: float | None = None

    def __post_init__(self) -> None:
        owner = "RoundedBox"
        dims = [_positive(owner, n, getattr(self, n)) for n in ("length", "width", "height")]
        r = float(self.edge_radius)
        if not (math.isfinite(r) and 0.0 <= r <= 0.5 * min(dims)):
            raise ValueError(
                f"{owner}.edge_radius must be in [0, {0.5 * min(dims):g}] m (half the smallest "
                f"side), got {self.edge_radius!r}"
            )
        if (self.density is None) == (self.mass is None):
            raise ValueError(f"{owner}: give exactly one of density [kg/m^3] or mass [kg]")
        if self.density is not None:
            _positive(owner, "density", self.density)
        if self.mass is not None:
            _positive(owner, "mass", self.mass)

    @property
    def half_inner(self) -> np.ndarray:
        """Half sizes of the inner (un-rounded) box [m], shape (3,)."""
        r = self.edge_radius
        return 0.5 * np.array([self.length, self.width, self.height]) - r

    def volume(self) -> float:
        """Exact volume of the sphere-swept box [m^3] (Steiner formula for a Minkowski sum)."""
        a, b, c = 2.0 * self.half_inner
        r = self.edge_radius
        return (
            a * b * c
            + 2.0 * r * (a * b + b * c + a * c)
            + math.pi * r * r * (a + b + c)
            + 4.0 / 3.0 * math.pi * r**3
        )

    def total_mass(self) -> float:
        return float(self.mass) if self.mass is not None else float(self.density) * self.volume()

    def inertia(self) -> np.ndarray:
        """Inertia tensor about the centre in the body frame [kg m^2], shape (3, 3).

        Exact for r = 0 (m (b^2 + c^2)/12, ...); with rounded edges, integrated numerically over
        a 120^3 midpoint grid of the shape's indicator (relative error ~1e-3, deterministic).
        """
        m = self.total_mass()
        a, b, c = self.length, self.width, self.height
        if self.edge_radius == 0.0:
            return m / 12.0 * np.diag([b * b + c * c, a * a + c * c, a * a + b * b])
        n = 120
        g = [(np.arange(n) + 0.5) / n * s - 0.5 * s for s in (a, b, c)]
        x, y, z = np.meshgrid(*g, indexing="ij")
        h = self.half_inner
        dx = np.maximum(np.abs(x) - h[0], 0.0)
        dy = np.maximum(np.abs(y) - h[1], 0.0)
        dz = np.maximum(np.abs(z) - h[2], 0.0)
        inside = dx * dx + dy * dy + dz * dz <= self.edge_radius**2
        w = inside / inside.sum()
        ixx = np.sum(w * (y * y + z * z))
        iyy = np.sum(w * (x * x + z * z))
        izz = np.sum(w * (x * x + y * y))
        return m * np.diag([ixx, iyy, izz])

    def corners(self) -> np.ndarray:
        """The 8 corners of the inner box in the body frame [m], shape (8, 3)."""
        h = self.half_inner
        s = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)], float)
        return s * h


@dataclass(frozen=True)
class PrescribedMotion:
    """Translational velocity [m/s] and angular velocity [rad/s] (world frame) times a time
    schedule, e.g. a belt roller turning at a fixed rate (the default schedule is 1 at all
    times) or a tilting tray (an angular velocity ramped on and off).

    With ``S(t) = integral of schedule from 0 to t`` [s] the body follows
    ``x(t) = x0 + v S(t)`` and ``R(t) = exp(w S(t)) R0``: exact for a fixed rotation axis.
    """

    velocity: tuple[float, float, float] = (0.0, 0.0, 0.0)
    angular_velocity: tuple[float, float, float] = (0.0, 0.0, 0.0)
    schedule: Schedule = field(default_factory=Schedule.constant)

    def __post_init__(self) -> None:
        v = np.asarray(self.velocity, float)
        w = np.asarray(self.angular_velocity, float)
        if v.shape != (3,) or w.shape != (3,) or not np.all(np.isfinite(np.r_[v, w])):
            raise ValueError(
                "PrescribedMotion: velocity and angular_velocity must be 3 finite "
                "numbers [m/s], [rad/s]"
            )
        if not isinstance(self.schedule, Schedule):
            raise TypeError("PrescribedMotion.schedule must be a Schedule")
