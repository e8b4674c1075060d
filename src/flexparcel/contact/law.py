"""RecurDyn-style contact law: normal force, velocity-dependent friction and a stick model.

This module implements the *law* only (force from penetration, penetration rate and tangential
slip), not the detection of contact points. It follows the paper's section 2.1, eqs. (1)-(10)
(Leitner et al., "MFBD of dimensionally unstable consignments"), which documents RecurDyn's
contact force:

* spring force, eq. (2): ``F_NC = c * s**m_s``;
* damping force, option "step", eq. (3): ``F_ND = STEP(s, 0, 0, s_max, d) * s'``;
  option "indentation", eq. (4): ``F_ND = d * sign(s') * |s'|**m_d * s**m_i``;
* normal force, eqs. (1), (5), (6): ``F_N = max(F_NC + F_ND, R_df * F_NC)`` (never pulls);
* friction, eqs. (7)-(10): ``|F_F| = |mu(v)| * F_N`` opposing the tangential slip velocity, with
  ``mu`` blended by STEP5 polynomials between the static and dynamic coefficients.

Beyond the paper there is an optional *stick model* (:func:`stick_friction`): an elastic
tangential spring with a Coulomb slip limit, integrated by a return map, so that a parcel resting on
a belt or an incline does not creep (the regularised law (8) has ``mu(0) = 0`` and therefore
always creeps).

Everything is in SI units (m, kg, s, N). The paper prints RecurDyn's N-kg-mm-s values; convert them
explicitly with :meth:`ContactLaw.from_paper_units`.

Per unit area. RecurDyn applies c and d per contact point, so the paper's 649 N/mm belongs to its
10 mm nodes (paper section 3.1: shell and solid elements of 10 mm edge length); at 25 mm the same
c would be (25/10)**2 = 6.25 times softer per unit of surface. flexparcel's law is therefore per
unit area of the slave surface: the spring coefficient c [N/m**(2 + m_s)], the damping d and the
stick stiffness k_t [N/m**3] are multiplied, at each contact point, by the point's tributary area
A [m**2] (a node: a third of each slave triangle around it, a quarter of each quad; see
:mod:`flexparcel.contact.tributary`), so a point's force is A * F_N(s, s') with the law below.
Line contact (a shell edge on a plane, a box or a face, and edge-to-edge contact) is per unit
length: a station of tributary length l carries the area l * w, w the set's strip width (default
:data:`REFERENCE_SPACING`), i.e. the per-length coefficients are c * w and d * w. Friction is
proportional to F_N and follows; the stick model's k_t is per area as well, so the creep bound
mu_s F_N / k_t of a point does not depend on its area. Areas and lengths are those of the
reference (undeformed) geometry, computed once when the model is built.

:meth:`ContactLaw.from_paper_units` converts the paper's per-point values through the reference
node spacing it states (``reference_spacing_mm``, default 10 mm): c_area = c / (10 mm)**2, so
649 N/mm = 6.49e9 N/m**3, and a 10 mm interior node gets 6.49e9 * 1e-4 = 649e3 N/m back. A law
given per point in SI units is built with the explicitly named :meth:`ContactLaw.from_point_values`.

Two layers:

* :class:`ContactLaw`, a validated, frozen description of one contact pair's law (storage,
  conversion, :meth:`ContactLaw.packed` for kernels);
* numba kernels over scalars and small flat arrays (``float64``), each returning the force and its
  exact derivatives, so that callers can assemble consistent Newton tangents. The ``*_packed``
  variants take the parameter vector from :meth:`ContactLaw.packed`; all kernels can be called from
  other numba kernels.

Packed parameter layout (``float64`` array of length :data:`PACKED_SIZE`)::

    index  name         symbol   unit                         note
    0      P_C          c        N/m**(2+m_s)                 spring stiffness per area
    1      P_M_S        m_s      -                            stiffness exponent
    2      P_OPTION     -        -                            0 = "step", 1 = "indentation"
    3      P_D          d        N s/m**3 ("step"),           damping coefficient per area
                                 N (s/m)**m_d / m**(2+m_i) ("indentation")
    4      P_S_MAX      s_max    m                            full-damping depth ("step")
    5      P_M_D        m_d      -                            damping exponent ("indentation")
    6      P_M_I        m_i      -                            indentation exponent ("indentation")
    7      P_R_DF       R_df     -                            rebound damping factor
    8      P_MU_S       mu_s     -                            static friction coefficient
    9      P_MU_D       mu_d     -                            dynamic friction coefficient
    10     P_V_S        v_s      m/s                          static threshold speed
    11     P_V_D        v_d      m/s                          dynamic threshold speed
    12     P_MAX_PEN    -        m                            max penetration (inf if none)
    13     P_K_T        k_t      N/m**3                       stick stiffness per area (0: none)
    14     P_SLIP_TANGENT -      -                            Newton tangent while slipping:
                                                              0 = consistent, 1 = stick (-k_t I),
                                                              2 = symmetric (see _return_map)

The kernels take these per-area values and a per-point scale (schedule factor times tributary
area [m**2]) from the contact set; the scalar kernels below are written per point (c in N/m**m_s)
and are called with the per-area values, their forces then multiplied by the area.

``P_SLIP_TANGENT`` is a solver choice, not physics: :meth:`ContactLaw.packed` writes 0 and the
integrator sets it (``IntegratorOptions.friction_tangent``). Forces never depend on it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace
from typing import Any

import numba as nb
import numpy as np

from flexparcel.model.checks import finite_number
from flexparcel.model.model import PACKED_LAW_SIZE

__all__ = [
    "ContactLaw",
    "DAMPING_OPTIONS",
    "DAMPING_STEP",
    "DAMPING_INDENTATION",
    "PACKED_SIZE",
    "P_C",
    "P_M_S",
    "P_OPTION",
    "P_D",
    "P_S_MAX",
    "P_M_D",
    "P_M_I",
    "P_R_DF",
    "P_MU_S",
    "P_MU_D",
    "P_V_S",
    "P_V_D",
    "P_MAX_PEN",
    "P_K_T",
    "P_SLIP_TANGENT",
    "REFERENCE_SPACING",
    "REFERENCE_AREA",
    "step",
    "step_dx",
    "step5",
    "step5_dx",
    "normal_force",
    "normal_force_packed",
    "friction_coefficient",
    "slip_friction_coefficient",
    "friction_force",
    "friction_force_packed",
    "stick_friction",
    "stick_friction_packed",
    "anchored_friction",
    "contact_friction",
]

# Damping option codes as stored in the packed vector (an int code keeps kernels branch-cheap).
DAMPING_STEP = 0
DAMPING_INDENTATION = 1
DAMPING_OPTIONS = {"step": DAMPING_STEP, "indentation": DAMPING_INDENTATION}

# Packed parameter layout: see the module docstring.
P_C = 0
P_M_S = 1
P_OPTION = 2
P_D = 3
P_S_MAX = 4
P_M_D = 5
P_M_I = 6
P_R_DF = 7
P_MU_S = 8
P_MU_D = 9
P_V_S = 10
P_V_D = 11
P_MAX_PEN = 12
P_K_T = 13
P_SLIP_TANGENT = 14
SLIP_TANGENT_CODES = {"consistent": 0.0, "stick": 1.0, "symmetric": 2.0}
"""``IntegratorOptions.friction_tangent`` -> the value of ``P_SLIP_TANGENT`` in a packed law."""
PACKED_SIZE = PACKED_LAW_SIZE  # the ground sizes empty law tables with it

# mm -> m. RecurDyn's N-kg-mm-s unit set differs from SI only in length.
_MM = 1.0e-3

REFERENCE_SPACING = 10.0 * _MM
"""The paper's node spacing [m]: RecurDyn's 10 mm shell and solid elements (paper section 3.1),
to which its per-point contact values belong; the default of
:meth:`ContactLaw.from_paper_units` and the default strip width of line contact."""

REFERENCE_AREA = REFERENCE_SPACING**2
"""Tributary area [m**2] of an interior node of a 10 mm mesh, 1e-4 m**2: the area over which a
paper per-point value is spread, and the area of a contact point without a surface of its own
(a rigid box's corner, see :meth:`flexparcel.builder.ModelBuilder.add_contact`)."""


# --------------------------------------------------------------------------------------------------
# Parameter object
# --------------------------------------------------------------------------------------------------


def _number(name: str, value: Any) -> float:
    return finite_number(f"ContactLaw.{name}", value)


@dataclass(frozen=True)
class ContactLaw:
    """The contact law of one contact pair (paper eqs. 1-10), SI units per unit area of the
    slave surface, validated on creation.

    Each contact point multiplies c, d and k_t by its tributary area A [m**2] (reference
    geometry; per unit length times the strip width for line contact, see the module
    docstring). Build it from the paper's per-point values with :meth:`from_paper_units`
    (through a stated reference spacing), from per-point SI values with
    :meth:`from_point_values`, or directly from per-area SI values.

    Attributes:
        stiffness: spring coefficient c per unit area [N/m**(2 + m_s)], > 0 (eq. 2): a point of
            area A has the spring A * c * s**m_s. With m_s = 1 it is N/m**3 (the paper's
            649 N/mm at its 10 mm nodes is 6.49e9 N/m**3).
        stiffness_exponent: m_s [-], >= 1 (eq. 2); 1 is a linear spring. Values below 1 would give
            an infinite tangent at first touch and are rejected.
        damping: d per unit area, >= 0 (eqs. 3, 4). Option "step": [N s/m**3]. Option
            "indentation": [N (s/m)**m_d / m**(2 + m_i)] (N s/m**3 when m_d = 1 and m_i = 0).
        damping_option: "step" (eq. 3: damping coefficient ramps by STEP from 0 at s = 0 to d at
            s = s_max) or "indentation" (eq. 4).
        damping_depth: s_max [m], > 0: penetration at which option "step" reaches the full damping
            d. flexparcel's default 0.1 mm; the paper does not report its value. Unused by
            "indentation" but still validated.
        damping_exponent: m_d [-], > 0 (eq. 4, option "indentation"). With m_d < 1 the damping
            tangent dF/ds' is infinite at s' = 0; prefer m_d >= 1 with implicit integrators.
        indentation_exponent: m_i [-], >= 0 (eq. 4, option "indentation"). Default 1 so that the
            damping force vanishes at first touch (no force jump); m_i = 0 gives constant damping.
        rebound_damping_factor: R_df [-] in [0, 1] (eqs. 5, 6): the normal force never drops below
            R_df * F_NC, so it never pulls.
        mu_static: mu_s [-], >= 0 (eqs. 8, 9).
        mu_dynamic: mu_d [-], >= 0 (eqs. 9, 10).
        v_static: v_s [m/s], > 0: slip speed at which |mu| reaches mu_s (eq. 8). Default 1 mm/s.
        v_dynamic: v_d [m/s], > v_s: slip speed from which mu = mu_d (eq. 10). Default 1.5 mm/s.
        max_penetration: [m], > 0, or None. Not part of the force law: callers flag or stop a run
            when a contact penetrates deeper (see :meth:`penetration_exceeded`).
        stick_stiffness: k_t per unit area [N/m**3], > 0, or None. When given, callers use the
            stick model (:func:`stick_friction` on planes, :func:`anchored_friction` on boxes and
            faces) instead of the regularised law (:func:`friction_force`): a tangential spring of
            stiffness A * k_t whose force is capped at mu_s * F_N while sticking; a resting
            contact then creeps by at most mu_s * F_N / (A k_t), which does not depend on the
            point's area A since F_N is proportional to it. See :meth:`with_stick_model`.
    """

    stiffness: float
    stiffness_exponent: float = 1.0
    damping: float = 0.0
    damping_option: str = "step"
    damping_depth: float = 1.0e-4
    damping_exponent: float = 1.0
    indentation_exponent: float = 1.0
    rebound_damping_factor: float = 0.0
    mu_static: float = 0.0
    mu_dynamic: float = 0.0
    v_static: float = 1.0e-3
    v_dynamic: float = 1.5e-3
    max_penetration: float | None = None
    stick_stiffness: float | None = None

    def __post_init__(self) -> None:
        # Store plain Python floats so that to_dict() is JSON-able whatever the caller passed
        # (ints, numpy scalars).
        def put(name: str, value: Any) -> None:
            object.__setattr__(self, name, value)

        checks = {
            "stiffness": ("c", "> 0 N/m**(2+m_s)", lambda v: v > 0.0),
            "stiffness_exponent": ("m_s", ">= 1", lambda v: v >= 1.0),
            "damping": ("d", ">= 0 (N s/m**3 for option 'step')", lambda v: v >= 0.0),
            "damping_depth": ("s_max", "> 0 m", lambda v: v > 0.0),
            "damping_exponent": ("m_d", "> 0", lambda v: v > 0.0),
            "indentation_exponent": ("m_i", ">= 0", lambda v: v >= 0.0),
            "rebound_damping_factor": ("R_df", "in [0, 1]", lambda v: 0.0 <= v <= 1.0),
            "mu_static": ("mu_s", ">= 0", lambda v: v >= 0.0),
            "mu_dynamic": ("mu_d", ">= 0", lambda v: v >= 0.0),
            "v_static": ("v_s", "> 0 m/s", lambda v: v > 0.0),
        }
        for name, (symbol, allowed, ok) in checks.items():
            v = _number(name, getattr(self, name))
            if not ok(v):
                raise ValueError(f"ContactLaw.{name} ({symbol}) must be {allowed}, got {v!r}")
            put(name, v)
        v_d = _number("v_dynamic", self.v_dynamic)
        if not v_d > self.v_static:
            raise ValueError(
                f"ContactLaw.v_dynamic (v_d) must be > v_static (v_s = {self.v_static!r} m/s), "
                f"got {v_d!r}"
            )
        put("v_dynamic", v_d)
        if self.damping_option not in DAMPING_OPTIONS:
            raise ValueError(
                f"ContactLaw.damping_option must be one of {sorted(DAMPING_OPTIONS)}, "
                f"got {self.damping_option!r}"
            )
        for name, symbol, unit in (
            ("max_penetration", "max_penetration", "m"),
            ("stick_stiffness", "k_t", "N/m**3"),
        ):
            raw = getattr(self, name)
            if raw is None:
                continue
            v = _number(name, raw)
            if not v > 0.0:
                raise ValueError(
                    f"ContactLaw.{name} ({symbol}) must be > 0 {unit} or None, got {v!r}"
                )
            put(name, v)

    def with_stick_model(self, stick_stiffness: float | None = None) -> ContactLaw:
        """This law with the stick model on: k_t = ``stick_stiffness`` [N/m**3, per area], by
        default the normal stiffness c of a linear law (m_s = 1), i.e. a tangential penalty as
        stiff as the normal one, whose slip before breaking loose is mu_s times the normal
        penetration."""
        if stick_stiffness is None:
            if self.stiffness_exponent != 1.0:
                raise ValueError(
                    "ContactLaw.with_stick_model: give stick_stiffness [N/m**3] for a nonlinear "
                    f"spring (stiffness_exponent = {self.stiffness_exponent!r})"
                )
            stick_stiffness = self.stiffness
        return replace(self, stick_stiffness=stick_stiffness)

    # ---------------------------------------------------------------------------------- conversion

    @classmethod
    def from_paper_units(
        cls,
        *,
        c_N_per_mm: float,
        d_Ns_per_mm: float = 0.0,
        s_max_mm: float = 0.1,
        stiffness_exponent: float = 1.0,
        damping_option: str = "step",
        damping_exponent: float = 1.0,
        indentation_exponent: float = 1.0,
        rebound_damping_factor: float = 0.0,
        mu_static: float = 0.0,
        mu_dynamic: float = 0.0,
        v_static_mm_s: float = 1.0,
        v_dynamic_mm_s: float = 1.5,
        max_penetration_mm: float | None = None,
        stick_stiffness_N_per_mm: float | None = None,
        reference_spacing_mm: float = 10.0,
    ) -> ContactLaw:
        """Build a per-area law from RecurDyn's per-point N-kg-mm-s values as printed in the
        paper (e.g. Table 6), through the node spacing they belong to.

        RecurDyn applies c and d per contact point, and the paper's values belong to its 10 mm
        nodes (paper section 3.1), i.e. to the tributary area ``reference_spacing_mm**2``. Two
        explicit steps:

        1. units: only lengths differ from SI (1 mm = 1e-3 m), so each coefficient is multiplied
           by 1000 per length unit in its denominator: c [N/mm**m_s] x 1000**m_s (611 N/mm =
           611e3 N/m); d, option "step" [N s/mm] x 1000; option "indentation"
           [N (s/mm)**m_d / mm**m_i] x 1000**(m_d + m_i) (x 1000 for m_d = 1, m_i = 0; with the
           default m_i = 1 the paper-unit value is in N s/mm**2 and is multiplied by 1e6 -- pass
           indentation_exponent=0 for plain N s/mm); stick stiffness k_t [N/mm] x 1000; lengths
           s_max, max_penetration [mm] x 1e-3; speeds v_s, v_d [mm/s] x 1e-3;
        2. per point -> per area: c, d and k_t are divided by the reference area
           ``(reference_spacing_mm * 1e-3)**2`` [m**2]: c_area = c / (10 mm)**2, so 649 N/mm =
           649e3 N/m / 1e-4 m**2 = 6.49e9 N/m**3, and an interior node of a 10 mm mesh
           (area 1e-4 m**2) has the paper's 649 N/mm again.
        """
        spacing = _number("reference_spacing", reference_spacing_mm) * _MM
        if not spacing > 0.0:
            raise ValueError(
                f"ContactLaw.from_paper_units: reference_spacing_mm must be > 0, "
                f"got {reference_spacing_mm!r}"
            )
        area = spacing * spacing
        c_exp = _number("stiffness_exponent", stiffness_exponent)
        if damping_option == "indentation":
            d_exp = _number("damping_exponent", damping_exponent) + _number(
                "indentation_exponent", indentation_exponent
            )
        else:
            d_exp = 1.0
        return cls(
            stiffness=_number("stiffness", c_N_per_mm) * (1.0 / _MM) ** c_exp / area,
            stiffness_exponent=stiffness_exponent,
            damping=_number("damping", d_Ns_per_mm) * (1.0 / _MM) ** d_exp / area,
            damping_option=damping_option,
            damping_depth=_number("damping_depth", s_max_mm) * _MM,
            damping_exponent=damping_exponent,
            indentation_exponent=indentation_exponent,
            rebound_damping_factor=rebound_damping_factor,
            mu_static=mu_static,
            mu_dynamic=mu_dynamic,
            v_static=_number("v_static", v_static_mm_s) * _MM,
            v_dynamic=_number("v_dynamic", v_dynamic_mm_s) * _MM,
            max_penetration=(
                None
                if max_penetration_mm is None
                else _number("max_penetration", max_penetration_mm) * _MM
            ),
            stick_stiffness=(
                None
                if stick_stiffness_N_per_mm is None
                else _number("stick_stiffness", stick_stiffness_N_per_mm) / _MM / area
            ),
        )

    def to_paper_units(self, reference_spacing_mm: float = 10.0) -> dict[str, Any]:
        """The keyword arguments of :meth:`from_paper_units` that rebuild this law (N-kg-mm-s,
        per point of a mesh of ``reference_spacing_mm`` spacing, which is among them)."""
        area = (reference_spacing_mm * _MM) ** 2
        if self.damping_option == "indentation":
            d_exp = self.damping_exponent + self.indentation_exponent
        else:
            d_exp = 1.0
        return {
            "c_N_per_mm": self.stiffness * area * _MM**self.stiffness_exponent,
            "d_Ns_per_mm": self.damping * area * _MM**d_exp,
            "s_max_mm": self.damping_depth / _MM,
            "stiffness_exponent": self.stiffness_exponent,
            "damping_option": self.damping_option,
            "damping_exponent": self.damping_exponent,
            "indentation_exponent": self.indentation_exponent,
            "rebound_damping_factor": self.rebound_damping_factor,
            "mu_static": self.mu_static,
            "mu_dynamic": self.mu_dynamic,
            "v_static_mm_s": self.v_static / _MM,
            "v_dynamic_mm_s": self.v_dynamic / _MM,
            "max_penetration_mm": (
                None if self.max_penetration is None else self.max_penetration / _MM
            ),
            "stick_stiffness_N_per_mm": (
                None if self.stick_stiffness is None else self.stick_stiffness * area * _MM
            ),
            "reference_spacing_mm": float(reference_spacing_mm),
        }

    @classmethod
    def from_point_values(
        cls,
        point_area: float,
        *,
        stiffness: float,
        damping: float = 0.0,
        stick_stiffness: float | None = None,
        **other: Any,
    ) -> ContactLaw:
        """The per-area law whose contact point of tributary area ``point_area`` [m**2] has the
        per-point SI values ``stiffness`` c [N/m**m_s], ``damping`` d [N s/m for option "step",
        N (s/m)**m_d / m**m_i for "indentation"] and ``stick_stiffness`` k_t [N/m]: each is
        divided by ``point_area``. RecurDyn's per-point semantics, explicitly: at another area
        a point gets proportionally more or less. ``other``: the remaining fields of the law,
        as for the constructor. E.g. ``from_point_values(REFERENCE_AREA, stiffness=1e5)`` is
        1e5 N/m at a 10 mm node and at a rigid box's corner (whose default area is
        :data:`REFERENCE_AREA`)."""
        a = _number("point_area", point_area)
        if not a > 0.0:
            raise ValueError(
                f"ContactLaw.from_point_values: point_area must be > 0 m**2, got {a!r}"
            )
        return cls(
            stiffness=_number("stiffness", stiffness) / a,
            damping=_number("damping", damping) / a,
            stick_stiffness=(
                None if stick_stiffness is None else _number("stick_stiffness", stick_stiffness) / a
            ),
            **other,
        )

    def to_dict(self) -> dict[str, Any]:
        """Plain, JSON-able dict of the SI field values (None for absent options)."""
        return {f.name: getattr(self, f.name) for f in fields(self)}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> ContactLaw:
        """Inverse of :meth:`to_dict`; unknown keys are an error (they would be silently lost)."""
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(data) - known)
        if unknown:
            raise ValueError(
                f"ContactLaw.from_dict: unknown keys {unknown}; known: {sorted(known)}"
            )
        return cls(**data)

    # ---------------------------------------------------------------------------------- kernels

    @property
    def damping_code(self) -> int:
        """Int code of :attr:`damping_option` (DAMPING_STEP or DAMPING_INDENTATION)."""
        return DAMPING_OPTIONS[self.damping_option]

    def packed(self) -> np.ndarray:
        """Parameters for the ``*_packed`` kernels, ``float64`` shape (PACKED_SIZE,).

        Layout in the module docstring; absent options are stored as max_penetration = inf and
        k_t = 0.
        """
        p = np.zeros(PACKED_SIZE, dtype=np.float64)
        p[P_C] = self.stiffness
        p[P_M_S] = self.stiffness_exponent
        p[P_OPTION] = self.damping_code
        p[P_D] = self.damping
        p[P_S_MAX] = self.damping_depth
        p[P_M_D] = self.damping_exponent
        p[P_M_I] = self.indentation_exponent
        p[P_R_DF] = self.rebound_damping_factor
        p[P_MU_S] = self.mu_static
        p[P_MU_D] = self.mu_dynamic
        p[P_V_S] = self.v_static
        p[P_V_D] = self.v_dynamic
        p[P_MAX_PEN] = np.inf if self.max_penetration is None else self.max_penetration
        p[P_K_T] = 0.0 if self.stick_stiffness is None else self.stick_stiffness
        return p

    def penetration_exceeded(self, s: float | np.ndarray) -> bool | np.ndarray:
        """Whether penetration s [m] (scalar or array) exceeds :attr:`max_penetration`.

        Always False when no maximum is set. The law itself keeps producing forces beyond it; the
        caller decides whether to flag, shorten the step or stop.
        """
        s_arr = np.asarray(s, dtype=np.float64)
        if self.max_penetration is None:
            out = np.zeros(s_arr.shape, dtype=bool)
        else:
            out = s_arr > self.max_penetration
        return bool(out) if out.ndim == 0 else out


# --------------------------------------------------------------------------------------------------
# STEP functions (RecurDyn / ADAMS): the paper's footnote 2 and design.md
# --------------------------------------------------------------------------------------------------


@nb.njit(cache=True)
def step(x: float, x0: float, h0: float, x1: float, h1: float) -> float:
    """Cubic STEP: h0 + (h1 - h0) D**2 (3 - 2 D), D = (x - x0)/(x1 - x0), clamped outside.

    C1 (zero slope at both ends). Requires x1 > x0.
    """
    if x <= x0:
        return h0
    if x >= x1:
        return h1
    dd = (x - x0) / (x1 - x0)
    return h0 + (h1 - h0) * dd * dd * (3.0 - 2.0 * dd)


@nb.njit(cache=True)
def step_dx(x: float, x0: float, h0: float, x1: float, h1: float) -> float:
    """d STEP / dx = (h1 - h0) 6 D (1 - D) / (x1 - x0); zero outside [x0, x1]."""
    if x <= x0 or x >= x1:
        return 0.0
    dd = (x - x0) / (x1 - x0)
    return (h1 - h0) * 6.0 * dd * (1.0 - dd) / (x1 - x0)


@nb.njit(cache=True)
def step5(x: float, x0: float, h0: float, x1: float, h1: float) -> float:
    """Quintic STEP5: h0 + (h1 - h0) D**3 (10 - 15 D + 6 D**2), clamped outside [x0, x1].

    C2 (zero slope and curvature at both ends). Requires x1 > x0.
    """
    if x <= x0:
        return h0
    if x >= x1:
        return h1
    dd = (x - x0) / (x1 - x0)
    return h0 + (h1 - h0) * dd * dd * dd * (10.0 - 15.0 * dd + 6.0 * dd * dd)


@nb.njit(cache=True)
def step5_dx(x: float, x0: float, h0: float, x1: float, h1: float) -> float:
    """d STEP5 / dx = (h1 - h0) 30 D**2 (1 - D)**2 / (x1 - x0); zero outside [x0, x1]."""
    if x <= x0 or x >= x1:
        return 0.0
    dd = (x - x0) / (x1 - x0)
    om = 1.0 - dd
    return (h1 - h0) * 30.0 * dd * dd * om * om / (x1 - x0)


# --------------------------------------------------------------------------------------------------
# Normal force, eqs. (1)-(6)
# --------------------------------------------------------------------------------------------------


@nb.njit(cache=True)
def normal_force(
    s: float,
    sdot: float,
    c: float,
    m_s: float,
    option: int,
    d: float,
    s_max: float,
    m_d: float,
    m_i: float,
    r_df: float,
) -> tuple[float, float, float]:
    """Normal contact force magnitude and its partial derivatives (paper eqs. 1-6).

    Args:
        s: penetration [m]; no contact (all zeros returned) for s <= 0.
        sdot: penetration rate s' [m/s], > 0 while approaching (penetration increasing).
        c, m_s: spring coefficient [N/m**m_s] and exponent (eq. 2).
        option: :data:`DAMPING_STEP` (eq. 3, uses d [N s/m], s_max [m]) or
            :data:`DAMPING_INDENTATION` (eq. 4, uses d, m_d, m_i).
        r_df: rebound damping factor in [0, 1] (eqs. 5, 6).

    Returns:
        (F_N [N] >= 0, dF_N/ds [N/m], dF_N/ds' [N s/m]). The force pushes the bodies apart along
        the contact normal. ``F_N = max(F_NC + F_ND, R_df F_NC)``; the derivatives are those of the
        branch taken (ties go to F_NC + F_ND). With option "indentation", m_d < 1 and s' = 0 the
        damping tangent is infinite and returned as inf.
    """
    if s <= 0.0:
        return 0.0, 0.0, 0.0
    # Spring, eq. (2). m_s >= 1 keeps the tangent finite as s -> 0+.
    f_nc = c * s**m_s
    df_nc = c * m_s * s ** (m_s - 1.0)
    if option == DAMPING_STEP:
        # Eq. (3): the damping coefficient ramps smoothly from 0 at first touch to d at s_max, so
        # the force does not jump when contact starts with a finite approach speed.
        coef = step(s, 0.0, 0.0, s_max, d)
        f_nd = coef * sdot
        df_nd_ds = step_dx(s, 0.0, 0.0, s_max, d) * sdot
        df_nd_dsdot = coef
    else:
        # Eq. (4): d * sign(s') |s'|**m_d * s**m_i (the paper writes sign(s') as s'/|s'|).
        a = abs(sdot)
        sgn = 1.0 if sdot > 0.0 else (-1.0 if sdot < 0.0 else 0.0)
        s_mi = s**m_i
        f_nd = d * sgn * a**m_d * s_mi
        df_nd_ds = 0.0 if m_i == 0.0 else d * sgn * a**m_d * m_i * s ** (m_i - 1.0)
        if a > 0.0:
            df_nd_dsdot = d * m_d * a ** (m_d - 1.0) * s_mi
        elif m_d == 1.0:
            df_nd_dsdot = d * s_mi
        elif m_d > 1.0:
            df_nd_dsdot = 0.0
        else:
            df_nd_dsdot = np.inf
    total = f_nc + f_nd
    f_min = r_df * f_nc
    # Eq. (6): the larger of eq. (1) and eq. (5). Since F_NC >= 0 and R_df >= 0 the result is
    # never negative: a separating contact is released, never glued.
    if total >= f_min:
        return total, df_nc + df_nd_ds, df_nd_dsdot
    return f_min, r_df * df_nc, 0.0


@nb.njit(cache=True)
def normal_force_packed(s: float, sdot: float, p: np.ndarray) -> tuple[float, float, float]:
    """:func:`normal_force` with parameters p from :meth:`ContactLaw.packed`, (PACKED_SIZE,)."""
    return normal_force(
        s,
        sdot,
        p[P_C],
        p[P_M_S],
        int(p[P_OPTION]),
        p[P_D],
        p[P_S_MAX],
        p[P_M_D],
        p[P_M_I],
        p[P_R_DF],
    )


# --------------------------------------------------------------------------------------------------
# Friction, eqs. (7)-(10)
# --------------------------------------------------------------------------------------------------


@nb.njit(cache=True)
def friction_coefficient(
    v: float, mu_s: float, mu_d: float, v_s: float, v_d: float
) -> tuple[float, float]:
    """Friction coefficient magnitude |mu(v)| and d|mu|/dv for the slip speed v [m/s] >= 0.

    Eq. (8), |v| <= v_s: mu = STEP5(v, -v_s, mu_s, v_s, -mu_s) is odd in v and passes through 0
    at v = 0, so |mu| rises from 0 at v = 0 to mu_s at v = v_s (slope 15/8 mu_s/v_s at 0).
    Eq. (9), v_s < |v| <= v_d: mu = STEP5(|v|, v_s, mu_s, v_d, mu_d). Eq. (10): mu = mu_d beyond.
    The joins at v_s and v_d are C2. The friction force is then -|mu(|v|)| F_N v/|v| (eq. 7, with
    the minus sign making it oppose the slip), continuous at v = 0 because mu(0) = 0.

    For v < 0 the value for |v| is returned and the derivative is d|mu(|v|)|/dv (the even
    extension; it has a kink at 0, so pass speeds, not signed velocities).
    """
    r = abs(v)
    sgn = 1.0 if v >= 0.0 else -1.0
    if r <= v_s:
        # |STEP5(r, -v_s, mu_s, v_s, -mu_s)| for r >= 0, expanded about the midpoint (t = r/v_s):
        # mu_s t (15 - 10 t**2 + 3 t**4)/8. Identical polynomial, but the literal STEP5 form
        # computes a small mu as a difference of two O(mu_s) numbers and loses digits near v = 0.
        t = r / v_s
        t2 = t * t
        mu = mu_s * t * (15.0 - 10.0 * t2 + 3.0 * t2 * t2) / 8.0
        dmu = 15.0 * mu_s * (1.0 - t2) * (1.0 - t2) / (8.0 * v_s)
    elif r <= v_d:
        mu = step5(r, v_s, mu_s, v_d, mu_d)
        dmu = step5_dx(r, v_s, mu_s, v_d, mu_d)
    else:
        mu = mu_d
        dmu = 0.0
    return mu, sgn * dmu


@nb.njit(cache=True)
def slip_friction_coefficient(
    v: float, mu_s: float, mu_d: float, v_s: float, v_d: float
) -> tuple[float, float]:
    """Coefficient used while *slipping* in the stick model, and its derivative, v [m/s] >= 0.

    Eqs. (9), (10) with the regularising branch (8) replaced by the plateau mu = mu_s for
    v <= v_s: in the stick model the tangential spring, not a vanishing mu, handles v -> 0, and
    a contact that just broke loose slides with mu_s (continuous with the stick limit), blending
    by STEP5 to mu_d between v_s and v_d.
    """
    r = abs(v)
    sgn = 1.0 if v >= 0.0 else -1.0
    if r <= v_s:
        return mu_s, 0.0
    if r <= v_d:
        return step5(r, v_s, mu_s, v_d, mu_d), sgn * step5_dx(r, v_s, mu_s, v_d, mu_d)
    return mu_d, 0.0


@nb.njit(cache=True)
def friction_force(
    vt: np.ndarray, f_n: float, mu_s: float, mu_d: float, v_s: float, v_d: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Regularised friction force (eq. 7) on the body whose tangential slip velocity is vt.

    Args:
        vt: tangential slip velocity [m/s], shape (3,): velocity of this body's contact point
            relative to the other surface (a belt's surface velocity already subtracted), already
            projected onto the tangent plane by the caller.
        f_n: normal force [N] >= 0.
        mu_s, mu_d, v_s, v_d: friction parameters (eqs. 8-10), speeds in m/s.

    Returns:
        F_T [N] shape (3,) = -|mu(|vt|)| F_N vt/|vt|; dF_T/dvt [N s/m] shape (3, 3) (w.r.t. the
        3-vector vt; compose with the tangent projector for the full kinematic Jacobian);
        dF_T/dF_N [-] shape (3,).

    Smoothness: writing F_T = -F_N h(|v|) v with h(r) = mu(r)/r, eq. (8) gives, for
    t = r/v_s <= 1, mu = mu_s t (15 - 10 t**2 + 3 t**4)/8, hence h = mu_s (15 - 10 t**2 + 3 t**4)
    / (8 v_s) is a polynomial in |v|**2: F_T is smooth at v = 0 with F_T(0) = 0 and
    dF_T/dv(0) = -(15/8) (mu_s/v_s) F_N I. This form is used for r <= v_s (no 0/0).
    """
    r = math.sqrt(vt[0] * vt[0] + vt[1] * vt[1] + vt[2] * vt[2])
    if r <= v_s:
        t2 = (r / v_s) ** 2
        k = mu_s / (8.0 * v_s)
        h = k * (15.0 - 10.0 * t2 + 3.0 * t2 * t2)
        # h'(r)/r = k (-20 + 12 t**2) / v_s**2: also free of divisions by r.
        hp_over_r = k * (-20.0 + 12.0 * t2) / (v_s * v_s)
    else:
        mu, dmu = friction_coefficient(r, mu_s, mu_d, v_s, v_d)
        h = mu / r
        hp_over_r = (dmu * r - mu) / (r * r * r)
    f = np.empty(3)
    df_dv = np.empty((3, 3))
    df_dfn = np.empty(3)
    for i in range(3):
        df_dfn[i] = -h * vt[i]
        f[i] = f_n * df_dfn[i]
        for j in range(3):
            df_dv[i, j] = -f_n * hp_over_r * vt[i] * vt[j]
        df_dv[i, i] -= f_n * h
    return f, df_dv, df_dfn


@nb.njit(cache=True)
def friction_force_packed(
    vt: np.ndarray, f_n: float, p: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`friction_force` with parameters from :meth:`ContactLaw.packed`."""
    return friction_force(vt, f_n, p[P_MU_S], p[P_MU_D], p[P_V_S], p[P_V_D])


# --------------------------------------------------------------------------------------------------
# Stick model (beyond the paper)
# --------------------------------------------------------------------------------------------------


@nb.njit(cache=True)
def stick_friction(
    u_el_prev: np.ndarray,
    du_t: np.ndarray,
    f_n: float,
    k_t: float,
    mu_s: float,
    mu_d: float,
    v_s: float,
    v_d: float,
    dt: float,
) -> tuple[np.ndarray, np.ndarray, bool, np.ndarray, np.ndarray]:
    """Elastic-slip (stick) friction by a return map over one time step.

    Model (Coulomb friction treated like elastoplasticity: Simo & Laursen, Comput. Struct. 42
    (1992) 97-116; Wriggers, *Computational Contact Mechanics*, 2nd ed., Springer 2006, on the
    tangential constitutive law and its return map): the tangential relative displacement splits
    into an elastic part u_el, carried by a spring k_t, and a slip part. Over a step with
    tangential relative displacement increment du_t:

    * trial: a = u_el_prev + du_t, T = k_t a;
    * stick if |T| <= mu_s F_N (the *static* coefficient caps sticking): F_T = -T, u_el = a;
    * slip otherwise: F_T = -mu_k(v) F_N a/|a|, u_el = mu_k(v) F_N a/(k_t |a|) (the spring is
      returned onto the slip limit), with mu_k from :func:`slip_friction_coefficient` (eqs. 9, 10
      with a plateau mu_s below v_s) at the slip speed v = |du_t|/dt.

    A resting contact therefore moves by at most mu_s F_N / k_t (the "creep bound").

    Args:
        u_el_prev: elastic tangential displacement at the start of the step [m], shape (3,), in
            the current tangent plane (the caller transports/projects it when the surface turns).
        du_t: tangential displacement increment of this body relative to the other surface over
            the step [m], shape (3,) (tangential; a belt's motion already subtracted).
        f_n: normal force at the end of the step [N] >= 0.
        k_t: tangential stiffness [N/m] > 0.
        mu_s, mu_d, v_s, v_d: friction parameters; speeds [m/s].
        dt: step size [s] > 0.

    Returns:
        (F_T [N] shape (3,), u_el_new [m] shape (3,), slipping flag, dF_T/d(du_t) [N/m]
        shape (3, 3) -- the consistent tangent of the return map --, dF_T/dF_N [-] shape (3,)).
        Stick: dF_T/d(du_t) = -k_t I. Slip: -F_N [mu_k (I - n n^T)/|a| + n (dmu_k/dv)
        du_t^T/(|du_t| dt)] with n = a/|a|.
    """
    return _stick_return_map(u_el_prev, du_t, f_n, k_t, mu_s, mu_d, v_s, v_d, dt, 0.0)


@nb.njit(cache=True)
def _stick_return_map(u_el_prev, du_t, f_n, k_t, mu_s, mu_d, v_s, v_d, dt, slip_tangent):
    f, u_new, slipping, dfd, dfv, dfn = _return_map(
        u_el_prev + du_t, du_t / dt, f_n, k_t, mu_s, mu_d, v_s, v_d, slip_tangent
    )
    # the slip speed is |du_t| / dt: d/d(du_t) = d/da + d/d(speed vector) / dt
    return f, u_new, slipping, dfd + dfv / dt, dfn


@nb.njit(cache=True)
def stick_friction_packed(
    u_el_prev: np.ndarray, du_t: np.ndarray, f_n: float, dt: float, p: np.ndarray
) -> tuple[np.ndarray, np.ndarray, bool, np.ndarray, np.ndarray]:
    """:func:`stick_friction` with parameters from :meth:`ContactLaw.packed` (needs k_t > 0);
    the tangent while slipping is set by ``p[P_SLIP_TANGENT]`` (see :func:`_return_map`)."""
    return _stick_return_map(
        u_el_prev,
        du_t,
        f_n,
        p[P_K_T],
        p[P_MU_S],
        p[P_MU_D],
        p[P_V_S],
        p[P_V_D],
        dt,
        p[P_SLIP_TANGENT],
    )


@nb.njit(cache=True)
def anchored_friction(
    a: np.ndarray, vt: np.ndarray, f_n: float, p: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Stick model for contacts whose surface moves and turns (a rigid box, a shell face).

    Same return map as :func:`stick_friction`, written for a *stick anchor*: a point fixed to
    the other surface (in its body frame, or by barycentric weights on a face) where the
    tangential spring is attached. ``a`` is the tangential part of (contact point - anchor),
    i.e. the trial elastic displacement of :func:`stick_friction`; keeping the anchor on the
    surface carries the history with the surface's own rigid motion and turning, which a world-
    frame u_el would not.

    * stick if k_t |a| <= mu_s F_N: F_T = -k_t a, elastic displacement a;
    * slip otherwise: F_T = -mu_k(|vt|) F_N a/|a|, elastic displacement mu_k F_N a/(k_t |a|)
      (the anchor is dragged along), mu_k from :func:`slip_friction_coefficient` at the current
      slip speed |vt| (eqs. 9, 10 with a plateau mu_s below v_s).

    Args:
        a: trial elastic tangential displacement [m], shape (3,).
        vt: tangential slip velocity [m/s], shape (3,) (sets mu_k while slipping).
        f_n: normal force [N] >= 0.
        p: packed law (:meth:`ContactLaw.packed`, k_t > 0).

    Returns:
        F_T [N] (3,), new elastic displacement [m] (3,) (the anchor moves to point - it),
        dF_T/da [N/m] (3, 3), dF_T/dvt [N s/m] (3, 3), dF_T/dF_N [-] (3,).
    """
    f, u_new, _, dfa, dfv, dfn = _return_map(
        a, vt, f_n, p[P_K_T], p[P_MU_S], p[P_MU_D], p[P_V_S], p[P_V_D], p[P_SLIP_TANGENT]
    )
    return f, u_new, dfa, dfv, dfn


@nb.njit(cache=True)
def contact_friction(stick, e, n, vt, f_n, p):
    """Friction of a contact point on a moving surface: the stick model on the tangential part
    ``a = e - (n . e) n`` of ``e`` (3,) = contact point - stick anchor [m] (``stick`` True), or
    the regularised law on the slip velocity ``vt`` (3,) [m/s].

    Returns (F_T (3,), new elastic displacement (3,), dF_T/da (3, 3), dF_T/dvt (3, 3),
    dF_T/dF_N (3,), n . e); without the stick model the elastic displacement and dF_T/da are
    zero. Callers chain dF_T/da with da = P de - n (e . dn) - (n . e) dn, P = I - n n^T.
    """
    en = n[0] * e[0] + n[1] * e[1] + n[2] * e[2]
    if stick:
        f, u_new, dfa, dfv, dfn = anchored_friction(e - en * n, vt, f_n, p)
        return f, u_new, dfa, dfv, dfn, en
    f, dfv, dfn = friction_force_packed(vt, f_n, p)
    return f, np.zeros(3), np.zeros((3, 3)), dfv, dfn, en


@nb.njit(cache=True)
def _return_map(a, v, f_n, k_t, mu_s, mu_d, v_s, v_d, slip_tangent):
    """The stick model's return map for the trial elastic displacement ``a`` (3,) [m], with
    ``v`` (3,) [m/s] the slip velocity that sets mu_k while slipping. Returns (F_T, new elastic
    displacement, slipping, dF_T/da, dF_T/dv, dF_T/dF_N).

    ``slip_tangent`` (``P_SLIP_TANGENT``) picks the derivatives while slipping; the force is
    the same for all three (quasi-Newton choices: Wriggers, *Computational Contact
    Mechanics*, 2006, on the non-symmetric friction tangent):

    * 0, consistent: dF_T/da = -mu F_N (I - n n^T)/|a|, with the F_N and mu(v) terms;
    * 1, stick: -k_t I as while sticking, nothing else. Newton converges linearly on slipping
      contacts but does not chase the consistent term, which flips with the slip direction
      n of a contact that barely slips;
    * 2, symmetric: -mu_k F_N (I - n n^T)/|a| - (1 - w) k_t n n^T with
      w = min(1, k_t |a| / (mu_s F_N) - 1): the consistent tangent without its F_N and
      mu(v) terms (so symmetric: Cholesky), and along n a stiffness that falls from k_t at
      the onset of slip to the consistent 0 once the trial displacement is twice the stick
      limit, so a contact at the onset does not switch between k_t and 0 from one iterate to
      the next. Along n the stick tangent's k_t stands for a force that does not grow: a
      body on many slipping contacts (a box sliding in its envelope) gets a tangent
      sum(k_t A) far above its inertia M / (beta h^2) along its slide, and each Newton
      correction moves it a small fraction of the way.
    """
    a_norm = math.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2])
    f = np.empty(3)
    u_new = np.empty(3)
    dfa = np.zeros((3, 3))
    dfv = np.zeros((3, 3))
    dfn = np.zeros(3)
    if k_t * a_norm <= mu_s * f_n:
        for i in range(3):
            f[i] = -k_t * a[i]
            u_new[i] = a[i]
            dfa[i, i] = -k_t
        return f, u_new, False, dfa, dfv, dfn
    # Slip; |a| > 0 because k_t |a| > mu_s F_N >= 0.
    speed = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    mu_k, dmu_k = slip_friction_coefficient(speed, mu_s, mu_d, v_s, v_d)
    # "symmetric": the consistent tangent's symmetric part, with a stiffness along n that
    # fades from k_t at the onset of slip to 0 at twice the stick limit (once per contact)
    limit = mu_s * f_n
    w = 1.0 if limit <= 0.0 else min(1.0, k_t * a_norm / limit - 1.0)
    across = mu_k * f_n / a_norm
    for i in range(3):
        ni = a[i] / a_norm
        f[i] = -mu_k * f_n * ni
        u_new[i] = mu_k * f_n * ni / k_t
        if slip_tangent == 2.0:
            for j in range(3):
                nn = ni * (a[j] / a_norm)  # exactly symmetric
                dfa[i, j] = -across * ((1.0 if i == j else 0.0) - nn) - (1.0 - w) * k_t * nn
            continue
        if slip_tangent != 0.0:
            dfa[i, i] = -k_t
            continue
        dfn[i] = -mu_k * ni
        for j in range(3):
            nj = a[j] / a_norm
            dfa[i, j] = -f_n * mu_k * ((1.0 if i == j else 0.0) - ni * nj) / a_norm
            # velocity dependence of mu_k; dmu_k = 0 on the plateau (including v = 0)
            if dmu_k != 0.0 and speed > 0.0:
                dfv[i, j] = -f_n * ni * dmu_k * v[j] / speed
    return f, u_new, True, dfa, dfv, dfn
