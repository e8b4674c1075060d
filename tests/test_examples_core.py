"""The structural-core example runs and gives physically sensible numbers."""

import runpy
from pathlib import Path

import pytest

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "shell_cantilever.py"


def test_shell_cantilever_example_runs():
    ns = runpy.run_path(str(EXAMPLE))
    assert ns["cantilever_end_shear"]() == pytest.approx(6.698, rel=5e-3)
    # after 0.2 s the free end has fallen well down, but no further than the free length
    # (0.255 m) allows; like a folding chain the tip may outrun free fall, so g t^2/2 is no bound
    z = ns["sheet_swing"]()
    assert -0.255 < z < -0.05


def test_box_on_belt_example_runs():
    ns = runpy.run_path(str(EXAMPLE.parent / "box_on_belt.py"))
    t_reach, t_exact = ns["box_on_belt"]()
    # the box slides at mu_d except for the last ~v_d of slip; with the paper's contact law
    # (611 N/mm per corner, STEP damping that vanishes at the micron penetrations of a resting
    # box) the box chatters on the belt and arrives 4 % late (measured): allow 5 %
    assert t_reach == pytest.approx(t_exact, rel=5e-2)
