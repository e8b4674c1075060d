"""Benchmark scene: a rigid 100 g box inside a two-layer 275 x 200 mm shell envelope, dropped
flat from 200 mm onto a rigid plate (the paper's horizontal drop test, simplified: no opening
and settling procedure yet; the envelope starts stress-free around the box).

Packaging: the KP/BW material of the paper's Table 6 (E = 926 MPa, nu = 0.1, beta = 1.71e-3 s),
0.3 mm thick, 40 g over both layers (140 g consignment minus the 100 g content). Content: the
KP/BW content box of Table 2, 165 x 125 x 20 mm, 3 mm edge radius. Contact laws: Table 6
(packaging-content 649 N/mm, 0.579 Ns/mm; packaging-ground 611 N/mm, 0.591 Ns/mm) with the STEP
damping option over s_max = 0.1 mm, friction 0.3 (the paper's friction values are not given),
by the stick model with k_t = c unless ``stick_model`` is False (then the paper's regularised
eq. 8; see :func:`flexparcel.consignments.build.default_packaging_content_law`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from flexparcel.builder import ModelBuilder
from flexparcel.contact.law import ContactLaw
from flexparcel.model.materials import ShellMaterial
from flexparcel.model.model import Model
from flexparcel.model.rigid import RoundedBox
from flexparcel.scenarios.envelope import two_layer_envelope

__all__ = ["EnvelopeDrop", "envelope_drop_model"]


@dataclass(frozen=True)
class EnvelopeDrop:
    length: float = 0.275
    width: float = 0.200
    thickness: float = 0.3e-3
    packaging_mass: float = 0.040
    content: tuple[float, float, float] = (0.165, 0.125, 0.020)
    content_mass: float = 0.100
    element_size: float = 0.010
    drop_height: float = 0.200
    t_end: float = 0.3
    stick_model: bool = True


def envelope_drop_model(case: EnvelopeDrop | None = None) -> tuple[Model, int, np.ndarray]:
    """Returns the model, the box's node id and the envelope's node ids."""
    c = case or EnvelopeDrop()
    gap = c.content[2] + 2e-3
    z0 = c.drop_height
    pts, quads, _, _ = two_layer_envelope(
        c.length, c.width, gap, c.element_size, origin=(0.0, 0.0, z0)
    )
    area = 2.0 * c.length * c.width
    rho = c.packaging_mass / (area * c.thickness)
    b = ModelBuilder(gravity=(0.0, 0.0, -9.81))
    env = b.add_shell_mesh(
        pts, quads, material=ShellMaterial(926e6, 0.1, rho, c.thickness, 1.71e-3)
    )
    box = b.add_rigid_body(
        RoundedBox(*c.content, edge_radius=3e-3, mass=c.content_mass),
        (0.0, 0.0, z0 + c.thickness / 2 + c.content[2] / 2 + 0.5e-3),
    )
    plate = b.add_plane((0.0, 0.0, 0.0), (0.0, 0.0, 1.0))
    # Table 6's per-point values at the paper's 10 mm nodes, per unit area (/ (10 mm)^2)
    content_law = ContactLaw.from_paper_units(
        c_N_per_mm=649, d_Ns_per_mm=0.579, s_max_mm=0.1, mu_static=0.3, mu_dynamic=0.3,
        reference_spacing_mm=10.0,
    )  # fmt: skip
    ground_law = ContactLaw.from_paper_units(
        c_N_per_mm=611, d_Ns_per_mm=0.591, s_max_mm=0.1, mu_static=0.3, mu_dynamic=0.3,
        reference_spacing_mm=10.0,
    )  # fmt: skip
    if c.stick_model:
        content_law, ground_law = content_law.with_stick_model(), ground_law.with_stick_model()
    b.add_body_contact(env, box, content_law, radius=c.thickness / 2)
    b.add_contact(env, plate, ground_law, radius=c.thickness / 2)
    return b.finalize(), box, env
