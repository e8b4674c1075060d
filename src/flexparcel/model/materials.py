"""Material data with validation. SI units throughout."""

from __future__ import annotations

import warnings
from dataclasses import dataclass

from flexparcel.model.checks import finite_number

__all__ = [
    "ShellMaterial",
    "MEMBRANE_LAWS",
    "validate_elastic",
    "UnitWarning",
    "PlausibilityWarning",
    "CoarseMeshWarning",
    "PLAUSIBLE_MIN_YOUNGS_MODULUS",
    "si_text",
]

PLAUSIBLE_MIN_YOUNGS_MODULUS = 1e5
"""Young's moduli below this [Pa] are warned about: softer than any packaging film, board
or content flexparcel models (soft foam and granulate are 0.1-10 MPa), but exactly what a
modulus in the paper's MPa (926 for KP/BW) looks like when typed into the SI API."""


class UnitWarning(UserWarning):
    """A value that is implausible in SI units but plausible in the paper's units (MPa,
    N/mm, mm): probably typed in the wrong unit. Silence it with
    ``warnings.simplefilter("ignore", UnitWarning)`` for deliberately non-dimensional models
    (e.g. patch tests with E = 1)."""


class PlausibilityWarning(UserWarning):
    """A value that is valid but almost certainly not meant (e.g. a dynamic friction
    coefficient above the static one); the message says why. Silence it with
    ``warnings.simplefilter("ignore", PlausibilityWarning)`` where it is meant."""


class CoarseMeshWarning(UserWarning):
    """A mesh coarser than the resolution a response is known to need; the message names the
    measured consequence. Coarse meshes stay usable as a low-fidelity level."""


def si_text(v: float) -> str:
    """``9.26e+08`` -> ``9.26e8`` (3 significant digits), as a message shows a value."""
    text = f"{v:.3g}"
    mant, sep, exp = text.partition("e")
    return f"{mant}e{int(exp)}" if sep else text


_si = si_text


def _check_finite(owner: str, name: str, value: float) -> float:
    return finite_number(f"{owner}.{name}", value)


def validate_elastic(mat, name: str, stacklevel: int = 4) -> None:
    """Check the isotropic elastic fields shared by shell and solid materials: finite numbers,
    E > 0, 0 <= nu < 0.5, rho > 0, Rayleigh beta >= 0; errors name the field and the range.

    A modulus below :data:`PLAUSIBLE_MIN_YOUNGS_MODULUS` (a value in MPa given as Pa, e.g.
    926 for 926 MPa) raises a :class:`UnitWarning` with the conversion; ``stacklevel``
    points it at the caller's line (4: the code that made the dataclass)."""
    e = _check_finite(name, "youngs_modulus", mat.youngs_modulus)
    nu = _check_finite(name, "poisson_ratio", mat.poisson_ratio)
    rho = _check_finite(name, "density", mat.density)
    beta = _check_finite(name, "damping_ratio", mat.damping_ratio)
    if e <= 0:
        raise ValueError(f"{name}.youngs_modulus must be > 0 Pa, got {e!r}")
    if not 0.0 <= nu < 0.5:
        raise ValueError(f"{name}.poisson_ratio must be in [0, 0.5), got {nu!r}")
    if rho <= 0:
        raise ValueError(f"{name}.density must be > 0 kg/m^3, got {rho!r}")
    if beta < 0:
        raise ValueError(f"{name}.damping_ratio (Rayleigh beta) must be >= 0 s, got {beta!r}")
    if e < PLAUSIBLE_MIN_YOUNGS_MODULUS:
        warnings.warn(
            f"{name}.youngs_modulus = {e:g} Pa is implausibly low for SI units (below "
            f"{PLAUSIBLE_MIN_YOUNGS_MODULUS:g} Pa); did you mean {e:g} MPa = {_si(e * 1e6)} Pa? "
            "flexparcel's Python API takes Pa (only the consignment files and --set take MPa)",
            UnitWarning,
            stacklevel=stacklevel,
        )


MEMBRANE_LAWS = ("elastic", "tension-field")
"""Membrane laws of :class:`ShellMaterial`: "elastic" (linear, carries compression as a
plate does) or "tension-field" (a compressive principal membrane stress is relaxed to zero:
the film wrinkles instead; see :mod:`flexparcel.elements.shell`)."""


@dataclass(frozen=True)
class ShellMaterial:
    """Isotropic linear-elastic shell material (small strain, used in the co-rotated frame).

    Attributes:
        youngs_modulus: Young's modulus E [Pa], > 0.
        poisson_ratio: Poisson's ratio nu [-], 0 <= nu < 0.5.
        density: mass density rho [kg/m^3], > 0.
        thickness: shell thickness t [m], > 0.
        damping_ratio: RecurDyn's FFlex "Damping Ratio", the stiffness-proportional Rayleigh
            coefficient beta [s] in C = beta * K (mass-proportional term zero). It is NOT a
            fraction of critical damping: mode i is damped with zeta_i = beta * omega_i / 2.
        membrane: membrane law, one of :data:`MEMBRANE_LAWS`. "tension-field" is for films
            far thinner than the mesh can wrinkle: a 0.3 mm film buckles under 0.07 % strain
            over a 10 mm span, so an element that shortens in-plane should carry no
            compression (Roddeman et al. 1987); bending (DKT) and damping stay linear.
    """

    youngs_modulus: float
    poisson_ratio: float
    density: float
    thickness: float
    damping_ratio: float = 0.0
    membrane: str = "elastic"

    def __post_init__(self) -> None:
        validate_elastic(self, "ShellMaterial")
        if self.membrane not in MEMBRANE_LAWS:
            raise ValueError(
                f"ShellMaterial.membrane must be one of {'|'.join(MEMBRANE_LAWS)}, "
                f"got {self.membrane!r}"
            )
        t = _check_finite("ShellMaterial", "thickness", self.thickness)
        if t <= 0:
            raise ValueError(f"ShellMaterial.thickness must be > 0 m, got {t!r}")

    @property
    def bending_stiffness(self) -> float:
        """Plate bending stiffness D = E t^3 / (12 (1 - nu^2)) [N m]."""
        e, nu, t = self.youngs_modulus, self.poisson_ratio, self.thickness
        return e * t**3 / (12.0 * (1.0 - nu * nu))
