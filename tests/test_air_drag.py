"""Air drag on shells (flexparcel.elements.air): tangents against finite differences, and a
falling plate against the closed form of quadratic drag."""

from __future__ import annotations

import math

import numpy as np
import pytest

import flexparcel as fp
from flexparcel.elements.air import AIR_DENSITY, AirDrag, _drag_kernel
from flexparcel.model.mesh import quads_to_triangles


def _kernel(tri, pos, vel, k, tangent=True):
    m = len(tri)
    fe, ke, ce = np.empty((m, 9)), np.zeros((m, 9, 9)), np.zeros((m, 9, 9))
    _drag_kernel(tri, pos, vel, np.full(m, k), fe, ke, ce, tangent)
    return fe, ke, ce


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_tangents_match_finite_differences(seed):
    # a general triangle moving obliquely (both signs of the normal velocity over the seeds)
    rng = np.random.default_rng(seed)
    tri = np.array([[0, 1, 2]])
    pos = rng.normal(size=(3, 3)) * 0.01
    vel = rng.normal(size=(3, 3))
    _, ke, ce = _kernel(tri, pos, vel, 0.7)
    eps = 1e-7  # central differences: truncation O(eps^2), round-off 1e-16/eps of the force
    kd, cd = np.empty((9, 9)), np.empty((9, 9))
    for c in range(9):
        n, d = divmod(c, 3)
        for x, out in ((pos, kd), (vel, cd)):
            xp, xm = x.copy(), x.copy()
            xp[n, d] += eps
            xm[n, d] -= eps
            args_p = (xp, vel) if x is pos else (pos, xp)
            args_m = (xm, vel) if x is pos else (pos, xm)
            out[:, c] = (_kernel(tri, *args_p, 0.7, False)[0][0]
                         - _kernel(tri, *args_m, 0.7, False)[0][0]) / (2 * eps)  # fmt: skip
    scale_k, scale_c = np.abs(kd).max(), np.abs(cd).max()
    np.testing.assert_allclose(ke[0], kd, atol=1e-6 * scale_k)
    np.testing.assert_allclose(ce[0], cd, atol=1e-6 * scale_c)
    # the damping matrix is symmetric positive semi-definite: drag only takes energy
    assert np.allclose(ce[0], ce[0].T) and np.linalg.eigvalsh(ce[0]).min() > -1e-12 * scale_c


def test_force_is_the_flat_plate_law_and_ignores_orientation_and_sliding():
    tri = np.array([[0, 1, 2]])
    pos = np.array([[0.0, 0, 0], [0.1, 0, 0], [0, 0.2, 0]])  # area 0.01 m^2, normal +z
    k = 0.5 * AIR_DENSITY * 1.17
    v = np.array([0.3, -0.4, -2.0])  # sliding in-plane and falling at 2 m/s
    fe, _, _ = _kernel(tri, pos, np.tile(v, (3, 1)), k)
    total = fe[0].reshape(3, 3).sum(axis=0)
    # internal force = minus the drag: the air pushes up on a falling plate, k A v_n^2
    np.testing.assert_allclose(total, [0.0, 0.0, -k * 0.01 * 4.0], rtol=1e-12, atol=1e-15)
    flipped, _, _ = _kernel(tri[:, ::-1].copy(), pos, np.tile(v, (3, 1)), k)
    np.testing.assert_allclose(flipped[0].reshape(3, 3).sum(axis=0), total, rtol=1e-12)


def _falling_plate(size, tilt_deg, cd, t_end):
    """A free square plate (areal density 0.13 kg/m^2, KP/BW's packaging) falling from rest
    under gravity with air drag; its plane turned ``tilt_deg`` about x from horizontal."""
    pts, quads = fp.mesh.rectangle(size, size, 2, 2)
    c, s = math.cos(math.radians(tilt_deg)), math.sin(math.radians(tilt_deg))
    pts = pts @ np.array([[1, 0, 0], [0, c, s], [0, -s, c]]).T
    b = fp.ModelBuilder(gravity=(0.0, 0.0, -9.81))
    t = 0.3e-3
    ids = b.add_shell_mesh(pts, quads, material=fp.ShellMaterial(926e6, 0.1, 0.13 / t, t, 0.0))
    tri, w = quads_to_triangles(ids[quads])
    b.add_element_group(AirDrag(tri, w, drag_coefficient=cd))
    model = b.finalize()
    r = fp.simulate(model, t_end, dt_out=t_end / 10)
    z = r.positions[:, :, 2].mean(axis=1)
    vz = r.velocities[:, :, 2].mean(axis=1)
    return r.time, z - z[0], vz, 0.13 * size**2


def test_a_falling_plate_follows_the_quadratic_drag_closed_form():
    # m dv/dt = m g - rho C_d A v^2 / 2: v = v_t tanh(g t / v_t), fall = v_t^2/g ln cosh(g t/v_t)
    # with v_t = sqrt(2 m g / (rho C_d A)) = 1.346 m/s here (Hoerner's plate, KP/BW's film)
    cd, size = 1.17, 0.1
    t, dz, vz, mass = _falling_plate(size, 0.0, cd, 0.4)
    vt = math.sqrt(2 * mass * 9.81 / (AIR_DENSITY * cd * size**2))
    v_exact = vt * np.tanh(9.81 * t / vt)
    fall_exact = vt**2 / 9.81 * np.log(np.cosh(9.81 * t / vt))
    # the integrator's error control (relative 1e-3 of the state per step) bounds the error
    # at a few 1e-3 of the closed form; 1 % leaves room and still tells drag from none (at
    # 0.4 s the fall is 0.36 m against 0.78 m in vacuum)
    np.testing.assert_allclose(-vz, v_exact, rtol=1e-2, atol=1e-4)
    np.testing.assert_allclose(-dz, fall_exact, rtol=1e-2, atol=1e-5)


def test_a_plate_falling_edge_on_feels_no_drag():
    t, dz, vz, _ = _falling_plate(0.1, 90.0, 1.17, 0.2)
    np.testing.assert_allclose(-vz, 9.81 * t, rtol=1e-6, atol=1e-9)


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"drag_coefficient": -1.0}, r"AirDrag.drag_coefficient must be in \[0, 5\]"),
        ({"air_density": 0.0}, r"AirDrag.air_density must be > 0 kg/m\^3"),
        ({"weights": np.ones(2)}, r"AirDrag.weights must be 1 numbers >= 0"),
    ],
)
def test_bad_input_names_the_field(kwargs, message):
    with pytest.raises(ValueError, match=message):
        AirDrag(np.array([[0, 1, 2]]), **kwargs)


def test_the_tests_put_the_drag_on_the_envelope_face_once(snapshot_dir):
    # a swing or drop with air_drag gets one AirDrag group over the top layer: its weighted
    # triangle area is the envelope's face (one plate), not both layers
    from flexparcel.consignments.snapshot import load_snapshot
    from flexparcel.model.mesh import triangle_areas
    from flexparcel.scenarios.registry import get_scenario

    snap = load_snapshot(snapshot_dir / "consignment_small" / "snapshot.npz")
    # the swing clamped where the nodes settled (jaws=None): closing the jaws (a simulation of
    # its own, run without drag) changes the start state, not the model's groups
    extra = {"swing": {"jaws": None}, "drop-horizontal": {}}
    for name in ("swing", "drop-horizontal"):
        scenario = get_scenario(name, air_drag=1.17, **extra[name])
        assert scenario._settings()["air_drag"] == 1.17
        model = scenario.build(snap, {}).model
        air = [g for g in model.element_groups if isinstance(g, AirDrag)]
        assert len(air) == 1 and air[0].drag_coefficient == 1.17
        area = float((air[0].weights * triangle_areas(model.positions0, air[0].triangles)).sum())
        length, width = snap.build.flat_size
        # the top layer's reference mesh: the flat size, its border ring sloping up to the
        # initial 2 mm gap (a few per mille more)
        assert length * width <= area < 1.01 * length * width
        without = get_scenario(name, **extra[name]).build(snap, {}).model
        assert not any(isinstance(g, AirDrag) for g in without.element_groups)
