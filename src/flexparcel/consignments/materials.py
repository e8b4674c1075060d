"""Packaging and content materials of the four paper consignments, with where each number
comes from.

The paper (section 3.1.1) measures the packaging thickness on the real consignments and sets the
density to match the real mass, but prints neither; it calibrates Young's modulus and the damping
ratio only for KP/BW (Table 6). Everything else below is a typical value for the material,
chosen and justified here, and is meant to be replaced by measurements (user TOML files may set
every field).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from flexparcel.model.materials import MEMBRANE_LAWS

__all__ = ["PackagingMaterial", "PACKAGING_PRESETS", "FLEXIBLE_CONTENT", "packaging_material"]


@dataclass(frozen=True)
class PackagingMaterial:
    """Shell properties of a packaging material (SI units).

    ``damping_ratio`` is RecurDyn's FFlex Damping Ratio: the stiffness-proportional Rayleigh
    coefficient beta [s] (C = beta K), not a fraction of critical damping.
    ``areal_density`` [kg/m^2] sets the packaging mass; the content gets the rest of the
    consignment's mass. ``membrane`` is the shell's membrane law
    (:data:`flexparcel.model.materials.MEMBRANE_LAWS`): "tension-field" lets the film wrinkle
    instead of carrying compression.
    """

    name: str
    youngs_modulus: float
    poisson_ratio: float
    thickness: float
    areal_density: float
    damping_ratio: float
    surface: str
    """Friction surface of the outside (pe_film, kraft_paper, bubble_wrap)."""
    source: str
    membrane: str = "elastic"

    def __post_init__(self) -> None:
        for key, lo in (("youngs_modulus", 0.0), ("thickness", 0.0), ("areal_density", 0.0)):
            v = getattr(self, key)
            if not (np.isfinite(v) and v > lo):
                raise ValueError(f"packaging material {self.name!r}: {key} must be > 0, got {v!r}")
        if not (np.isfinite(self.poisson_ratio) and 0.0 <= self.poisson_ratio < 0.5):
            raise ValueError(
                f"packaging material {self.name!r}: poisson_ratio must be in [0, 0.5), "
                f"got {self.poisson_ratio!r}"
            )
        if self.membrane not in MEMBRANE_LAWS:
            raise ValueError(
                f"packaging material {self.name!r}: membrane must be one of "
                f"{'|'.join(MEMBRANE_LAWS)}, got {self.membrane!r}"
            )
        if not (np.isfinite(self.damping_ratio) and self.damping_ratio >= 0.0):
            raise ValueError(
                f"packaging material {self.name!r}: damping_ratio (beta) must be >= 0 s, "
                f"got {self.damping_ratio!r}"
            )

    @property
    def density(self) -> float:
        """Volume density [kg/m^3] of the shell that gives ``areal_density``."""
        return self.areal_density / self.thickness


PACKAGING_PRESETS: dict[str, PackagingMaterial] = {
    "kraft_paper_bubble_wrap": PackagingMaterial(
        "kraft_paper_bubble_wrap",
        youngs_modulus=926e6,
        poisson_ratio=0.1,
        thickness=0.3e-3,
        areal_density=0.130,
        damping_ratio=1.71e-3,
        surface="kraft_paper",
        source=(
            "E = 926 MPa and beta = 1.71e-3 s: paper Table 6 (calibrated on KP/BW); nu = 0.1: "
            "paper 3.1.1 (kraft paper); thickness 0.3 mm: an effective shell thickness (kraft "
            "paper 0.1-0.15 mm laminated to a bubble lining; the paper does not print its "
            "measured value); 130 g/m^2: kraft 80-90 g/m^2 plus a PE bubble lining of "
            "40-50 g/m^2, typical mailer values (about 15 g for a 275 x 200 mm envelope)"
        ),
    ),
    "polybag": PackagingMaterial(
        "polybag",
        youngs_modulus=250e6,
        poisson_ratio=0.4,
        thickness=0.06e-3,
        areal_density=0.055,
        damping_ratio=1.71e-3,
        surface="pe_film",
        source=(
            "LDPE mailing-bag film 50-80 um thick, E = 200-300 MPa (typical LDPE), density "
            "920 kg/m^3 -> 55 g/m^2 at 60 um; nu = 0.4: paper 3.1.1 (plastic); beta: the "
            "KP/BW value of Table 6 (uncalibrated for PB)"
        ),
    ),
    "kraft_paper": PackagingMaterial(
        "kraft_paper",
        youngs_modulus=3.0e9,
        poisson_ratio=0.1,
        thickness=0.2e-3,
        areal_density=0.150,
        damping_ratio=1.71e-3,
        surface="kraft_paper",
        source=(
            "heavy kraft paper 120-160 g/m^2, 0.15-0.25 mm; E = 2-5 GPa (in-plane, between "
            "machine and cross direction; isotropic here); nu = 0.1: paper 3.1.1; beta: the "
            "KP/BW value of Table 6 (uncalibrated for KP)"
        ),
    ),
    "bubble_wrap": PackagingMaterial(
        "bubble_wrap",
        youngs_modulus=60e6,
        poisson_ratio=0.4,
        thickness=0.5e-3,
        areal_density=0.080,
        damping_ratio=1.71e-3,
        surface="bubble_wrap",
        source=(
            "bubble-wrap pouch: two PE films of 40-50 um with bubbles between (about 4 mm "
            "overall); as one shell: an effective 0.5 mm thick layer with E = 60 MPa, which "
            "gives roughly the bending stiffness of the bubbled laminate; 80 g/m^2 (two films "
            "plus bubbles); nu = 0.4: paper 3.1.1 (plastic); beta: the KP/BW value"
        ),
    ),
}

FLEXIBLE_CONTENT = {
    "youngs_modulus": 0.5e6,
    "poisson_ratio": 0.3,
    "damping_ratio": 5e-3,
    "source": (
        "granulate (perlite / expanded clay) in a plastic bag, as one soft solid: E = 0.5 MPa "
        "(a loose granular bed under light confinement is 0.1-10 MPa), nu = 0.3; beta = 5e-3 s "
        "(the top of the paper's range) for the granulate's internal friction"
    ),
}


def packaging_material(name: str, **overrides: float) -> PackagingMaterial:
    """The preset for ``name`` (one of :data:`PACKAGING_PRESETS`), with fields overridden."""
    if name not in PACKAGING_PRESETS:
        raise ValueError(
            f"unknown packaging material {name!r}; allowed: {', '.join(PACKAGING_PRESETS)}"
        )
    mat = PACKAGING_PRESETS[name]
    return replace(mat, **overrides) if overrides else mat
