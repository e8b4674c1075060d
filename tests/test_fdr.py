"""FDR (RBE2) rigid links and fixed joints."""

import numpy as np
import pytest

import flexparcel as fp
from conftest import strip_model
from flexparcel.elements.rotations import rotation_exp
from flexparcel.model.rigid import RoundedBox


def test_fdr_transmits_a_follower_moment_full_circle():
    # Sze 3.2 with the tip moment applied to an FDR reference node tying the tip edge: the
    # strip still rolls up into the exact full circle (theta = 2 pi at M = Mmax); the FDR keeps
    # the tip edge straight, which pure bending does anyway. Tolerance as for Sze 3.2: 2e-3 L.
    length, mmax = 12.0, 50.0 * np.pi / 3.0
    b, tip, _ = strip_model(length, 1.0, 0.1, 16)
    ref = b.add_fdr(tip)
    b.add_moment(ref, (0.0, -mmax, 0.0), follower=True)
    res = fp.solve_static(b.finalize(), load_steps=20)
    th = 2.0 * np.pi * res.load_factors
    r = length / th
    w = res.displacements[:, tip, 2].mean(axis=1)
    u = -res.displacements[:, tip, 0].mean(axis=1)
    assert np.abs(w - r * (1 - np.cos(th))).max() <= 2e-3 * length
    assert np.abs(u - (length - r * np.sin(th))).max() <= 2e-3 * length
    # the tip nodes keep their distance (rigid link)
    d = res.states[-1].positions[tip[1]] - res.states[-1].positions[tip[0]]
    assert np.linalg.norm(d) == pytest.approx(1.0, rel=1e-12)


def test_nodes_tied_to_a_rigid_body_move_rigidly_with_it():
    # a free box carrying a small shell patch tied to it (a fixed joint between the FDR and the
    # body) spins and falls: the patch nodes stay at their body-frame offsets, the centre of
    # mass falls at exactly g (generalized-alpha is exact for constant acceleration)
    b = fp.ModelBuilder()
    box = b.add_rigid_body(RoundedBox(0.1, 0.1, 0.02, 0.0, mass=0.2), (0.0, 0.0, 1.0))
    pts, quads = fp.mesh.rectangle(0.04, 0.04, 2, 2, origin=(-0.02, -0.02, 1.01))
    ids = b.add_shell_mesh(pts, quads, material=fp.ShellMaterial(1e9, 0.3, 1000.0, 1e-3, 1e-4))
    b.add_fdr(ids, reference=box)
    model = b.finalize()
    assert model.dof_count == 6  # only the box's DOFs are unknowns
    s = model.initial_state()
    s.velocities[box, 3:] = (0.0, 0.0, 3.0)
    s.velocities[ids, :3] = np.cross((0.0, 0.0, 3.0), pts - (0.0, 0.0, 1.0))
    s.velocities[ids, 3:] = (0.0, 0.0, 3.0)
    r = fp.simulate(model, 0.2, state=s, dt_out=0.05)
    rot = rotation_exp(r.rotation_vectors[-1, box])
    expect = r.positions[-1, box] + (rot @ (pts - (0.0, 0.0, 1.0)).T).T
    np.testing.assert_allclose(r.positions[-1, ids], expect, atol=1e-12)
    m_total = model.total_mass()
    com = (model.mass[:, 0] @ r.positions[-1]) / m_total
    z0 = (model.mass[:, 0] @ model.positions0)[2] / m_total
    assert com[2] == pytest.approx(z0 - 0.5 * 9.81 * 0.2**2, abs=1e-9)
    assert r.rotation_vectors[-1, box, 2] == pytest.approx(0.6, rel=1e-6)  # w constant


def test_fixed_joint_welds_two_bodies():
    b = fp.ModelBuilder(gravity=(0.0, 0.0, 0.0))
    a = b.add_rigid_body(RoundedBox(0.1, 0.1, 0.1, 0.0, mass=1.0), (0.0, 0.0, 0.0))
    c = b.add_rigid_body(RoundedBox(0.1, 0.1, 0.1, 0.0, mass=1.0), (0.2, 0.0, 0.0))
    b.add_fixed_joint(a, c)
    model = b.finalize()
    s = model.initial_state()
    s.velocities[a, 3:] = (0.0, 0.0, 1.0)
    s.velocities[c] = (0.0, 0.2, 0.0, 0.0, 0.0, 1.0)
    r = fp.simulate(
        model, 1.0, state=s, dt_out=0.5, options=fp.IntegratorOptions(tol_displacement=1e-8)
    )
    gap = np.linalg.norm(r.positions[:, c] - r.positions[:, a], axis=1)
    np.testing.assert_allclose(gap, 0.2, rtol=1e-12)


def test_fdr_bad_input():
    b, tip, _ = strip_model(1.0, 1.0, 0.01, 2)
    with pytest.raises(ValueError, match=r"cannot be tied to itself"):
        b.add_fdr(tip, reference=int(tip[0]))
    ref = b.add_fdr(tip)
    with pytest.raises(ValueError, match=r"already tied"):
        b.add_fdr(tip[:1])
    with pytest.raises(ValueError, match=r"add_fdr: node id 99 is outside"):
        b.add_fdr([99])
    b.fix(tip[0], "all")
    with pytest.raises(ValueError, match=r"tied to node .* cannot also be fixed"):
        b.finalize()
    assert ref == 6
