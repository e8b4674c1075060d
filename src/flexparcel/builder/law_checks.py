"""Plausibility checks of a contact law as the builder takes it: values that are valid SI but
almost certainly a mistake get a warning that says why and what was probably meant.

* A linear spring (m_s = 1) softer than :data:`PLAUSIBLE_MIN_CONTACT_STIFFNESS` [N/m^3, per
  unit area] is what the paper's per-point N/mm value looks like when typed into the SI law
  (649 for Table 6's 649 N/mm): :class:`~flexparcel.model.materials.UnitWarning` with the
  conversion through :meth:`ContactLaw.from_paper_units`.
* ``mu_dynamic > mu_static``: :class:`~flexparcel.model.materials.PlausibilityWarning` with
  the reason (a warning, not an error: velocity-strengthening friction exists, e.g. some
  rubbers on steel, and a user may mean it).

The checks live in the builder, where every contact pair's law comes in
(:func:`check_law`), so that the law itself stays a plain validated value.
"""

from __future__ import annotations

import os
import sys
import warnings

from flexparcel.contact.law import REFERENCE_AREA, ContactLaw
from flexparcel.model.materials import PlausibilityWarning, UnitWarning, si_text

__all__ = ["PLAUSIBLE_MIN_CONTACT_STIFFNESS", "check_law"]

PLAUSIBLE_MIN_CONTACT_STIFFNESS = 1e5
"""Linear contact stiffnesses per unit area below this [N/m^3] are warned about. A paper
value in N/mm per 10 mm node (Table 6: 611, 649; Table 4's ranges 100-1000; the conveyor's
content stiffness 1-1e4) typed as SI gives 1 to 1e4. At 1e5 N/m^3 a 10 mm node already has
only 10 N/m, and a 100 g box lying on 100 cm^2 sinks 1 mm; real contacts of packaging are
1e7 to 1e11 N/m^3 (Table 6's 649 N/mm is 6.49e9)."""


def _user_stacklevel() -> int:
    """``stacklevel`` for :func:`warnings.warn` called in this module that points at the
    first frame outside the builder package: the user's ``add_*`` call, however deep the
    builder's own calls are."""
    here = os.path.dirname(__file__)
    frame, level = sys._getframe(1), 1
    while frame is not None and frame.f_code.co_filename.startswith(here):
        frame, level = frame.f_back, level + 1
    return level


def check_law(name: str, law: ContactLaw) -> None:
    """Warn (see the module docstring) about ``law`` given to the builder's ``name``."""
    c = law.stiffness
    # the exponent changes the unit (N/m^(2 + m_s)): only a linear spring has one threshold
    if law.stiffness_exponent == 1.0 and c < PLAUSIBLE_MIN_CONTACT_STIFFNESS:
        meant = c * 1e3 / REFERENCE_AREA  # c [N/mm] at a 10 mm node -> N/m -> per m^2
        warnings.warn(
            f"{name}: ContactLaw.stiffness = {c:g} N/m^3 (per unit area) is implausibly low "
            f"for SI units (below {PLAUSIBLE_MIN_CONTACT_STIFFNESS:g} N/m^3); did you mean "
            f"{c:g} N/mm per 10 mm node, as the paper prints it? That is "
            f"ContactLaw.from_paper_units(c_N_per_mm={c:g}) = {si_text(meant)} N/m^3 "
            f"({si_text(c * 1e3)} N/m at a 10 mm node)",
            UnitWarning,
            stacklevel=_user_stacklevel(),
        )
    if law.mu_dynamic > law.mu_static:
        hint = " (mu_static was left at its default 0?)" if law.mu_static == 0.0 else ""
        warnings.warn(
            f"{name}: ContactLaw.mu_dynamic = {law.mu_dynamic:g} > mu_static = "
            f"{law.mu_static:g}{hint}: friction then grows with the slip speed (the law blends "
            "from mu_static at v_static to mu_dynamic at v_dynamic, paper eqs. 8-10), and a "
            "sticking contact breaks loose at mu_static F_N into a slip that needs more "
            "force. Packaging on belts and steel is measured with mu_static >= mu_dynamic; "
            "give mu_static >= mu_dynamic unless you mean velocity-strengthening friction",
            PlausibilityWarning,
            stacklevel=_user_stacklevel(),
        )
