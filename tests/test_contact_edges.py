"""Line contact: a sheet standing on its edge."""

import numpy as np
import pytest

import flexparcel as fp
from flexparcel.contact.law import ContactLaw


def test_sheet_lands_on_its_edge_and_carries_its_weight():
    # A 200 x 100 mm sheet in the vertical xz-plane (out-of-plane motion held) falls 2 mm onto
    # a plate edge first. At rest the line contact carries its weight W: with a linear law
    # spread over E edges (3 stations of c/3 each), the edge sinks s = W / (E c) = 1.4 um;
    # within 10 % (the edge's nodes share the load unevenly near its ends).
    t, rho = 0.3e-3, 2424.0
    pts, quads = fp.mesh.rectangle(0.2, 0.1, 10, 5)
    pts = np.column_stack([pts[:, 0], np.zeros(len(pts)), pts[:, 1] + 0.002])
    b = fp.ModelBuilder()
    ids = b.add_shell_mesh(pts, quads, material=fp.ShellMaterial(926e6, 0.1, rho, t, 1.71e-3))
    b.fix(ids, ["y", "rx", "rz"])
    bottom = ids[np.isclose(pts[:, 2], 0.002)]
    c = 1e4
    law = ContactLaw(
        stiffness=c, damping=5.0, damping_option="indentation", indentation_exponent=0.0
    )
    b.add_edge_contact(bottom, b.add_plane((0, 0, 0), (0, 0, 1)), law)
    model = b.finalize()
    r = fp.simulate(model, 0.3, dt_out=0.01)
    weight = model.total_mass() * 9.81
    sink = -r.positions[-1, bottom, 2].mean()
    assert sink == pytest.approx(weight / (10 * c), rel=0.1)
    assert np.abs(r.velocities[-1, ids, 2]).max() < 1e-3


def test_edge_contact_bad_input():
    b = fp.ModelBuilder()
    pts, quads = fp.mesh.rectangle(0.1, 0.1, 2, 2)
    ids = b.add_shell_mesh(pts, quads, material=fp.ShellMaterial(1e9, 0.3, 1000.0, 1e-3))
    plane = b.add_plane((0, 0, 0), (0, 0, 1))
    law = ContactLaw(stiffness=1e4)
    with pytest.raises(ValueError, match=r"unknown plane 5"):
        b.add_edge_contact(ids, 5, law)
    with pytest.raises(ValueError, match=r"no shell edge"):
        b.add_edge_contact(ids[[0, 8]], plane, law)
    with pytest.raises(ValueError, match=r"samples must be an integer >= 1"):
        b.add_edge_contact(ids, plane, law, samples=0)
