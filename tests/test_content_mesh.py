"""The rounded-block solid mesh of a flexible content (hex8, wedge6, tet4): valid elements,
a conforming mesh on the rounded surface, the volume of Steiner's formula in the limit, and
the patch test across the element kinds."""

from __future__ import annotations

import numpy as np
import pytest

from flexparcel.builder.model_builder import _SOLID_FACES, _solid_boundary_faces
from flexparcel.consignments.content_mesh import rounded_block, rounded_block_volume
from flexparcel.elements.solid import SolidMaterial, solid_reference_data

MATERIAL = SolidMaterial(1.0e6, 0.3, 1000.0, 0.0)
PB = ((0.31, 0.225, 0.02), 0.01)  # PB's content: a flat core, rounded with half its height
BOX = ((0.2, 0.1, 0.06), 0.015)  # an inner box of extent along all three axes


def _inner(size, radius):
    return 0.5 * np.asarray(size) - radius


def _distance_to_inner_box(points, size, radius):
    a = _inner(size, radius)
    return np.linalg.norm(points - np.clip(points, -a, a), axis=1)


@pytest.mark.parametrize(("size", "radius"), [PB, BOX], ids=["flat-core", "box"])
@pytest.mark.parametrize("h", [0.025, 0.01, 0.005])
def test_elements_are_valid_and_the_mesh_conforms(size, radius, h):
    mesh = rounded_block(size, radius, h)
    assert set(mesh.cells) == {"hex8", "wedge6", "tet4"}
    for kind, cells in mesh.cells.items():
        # raises for a Jacobian <= 0 at any Gauss point; every element has volume
        ref = solid_reference_data(mesh.points, cells, kind, MATERIAL)
        assert np.all(ref.volume > 0), kind
    assert np.unique(np.concatenate([c.ravel() for c in mesh.cells.values()])).size == len(
        mesh.points
    )  # no stray node
    # Conforming: a face is shared by two elements or lies on the outer surface. A gap
    # between two regions (nodes not merged, a face split differently on both sides) would
    # leave boundary faces inside the block, away from the surface.
    count: dict = {}
    for cells in mesh.cells.values():
        for face in _SOLID_FACES[cells.shape[1]]:
            for row in cells[:, face].tolist():
                key = tuple(sorted(row))
                count[key] = count.get(key, 0) + 1
    assert max(count.values()) == 2
    outer = np.unique(np.concatenate([np.array(f) for f in _solid_boundary_faces(
        list(mesh.cells.values()))]))  # fmt: skip
    d = _distance_to_inner_box(mesh.points[outer], size, radius)
    np.testing.assert_allclose(d, radius, rtol=1e-9)
    # and the block has its outer size
    np.testing.assert_allclose(np.ptp(mesh.points, axis=0), size, rtol=1e-12)


@pytest.mark.parametrize("fine", [0.005, pytest.param(0.0025, marks=pytest.mark.slow)])
@pytest.mark.parametrize(("size", "radius"), [PB, BOX], ids=["flat-core", "box"])
def test_volume_converges_to_steiners_formula_at_the_rate_of_the_chords(size, radius, fine):
    """The rounded surface is resolved by chords, n_t per quarter circle: a quarter disc
    loses 1 - (2 n / pi) sin(pi / 2n) ~ (pi / 2n)^2 / 6 of its area (10 % at n = 2, 1.1 %
    at n = 6), and the octants lose the same order. So the volume error falls as 1 / n_t^2:
    from n_t = 2 (h = 10 mm) to 3 (r = 10 mm) or 5 (r = 15 mm) at h = 5 mm, by 2.25 or 6.25
    (slow: 6 or 9 at 2.5 mm, by 9 or 20). Bounds: the error is a deficit (the chords lie
    inside), below the quarter disc's own deficit at each n (the flat parts are exact), and
    its fall is (n2 / n1)^2 within a third (the octants' and the cylinders' shares change a
    little with n; measured 0.98 and 0.95 at 5 mm, 0.96 and 0.95 at 2.5 mm)."""
    exact = rounded_block_volume(size, radius)
    errors = {}
    for h in (0.01, fine):
        mesh = rounded_block(size, radius, h)
        n_t = max(2, round(0.5 * np.pi * radius / h))
        vol = sum(
            float(solid_reference_data(mesh.points, c, k, MATERIAL).volume.sum())
            for k, c in mesh.cells.items()
        )
        err = 1.0 - vol / exact
        assert 0.0 < err < 1.0 - (2 * n_t / np.pi) * np.sin(np.pi / (2 * n_t)), (h, err)
        errors[n_t] = err
    (n1, e1), (n2, e2) = sorted(errors.items())
    assert n1 == 2 and n2 >= 3
    assert 0.67 < (e1 / e2) / (n2 / n1) ** 2 < 1.33, errors


def test_steiners_formula_is_the_limits():
    # r -> 0: the box; r = half of every side: the sphere
    assert rounded_block_volume((0.3, 0.2, 0.1), 1e-12) == pytest.approx(0.006, rel=1e-9)
    assert rounded_block_volume((0.2, 0.2, 0.2), 0.1) == pytest.approx(4 / 3 * np.pi * 1e-3)


@pytest.mark.parametrize(("size", "radius"), [PB, BOX], ids=["flat-core", "box"])
def test_constant_strain_patch_across_the_element_kinds(size, radius):
    """A linear displacement u = G x (a constant strain) must leave every node that is not
    on the outer surface in equilibrium: the element kinds meet in a conforming mesh and each
    represents a constant strain exactly (the patch test). Tolerance 1e-9 of the largest
    nodal force: round-off of sums of order-1 entries."""
    mesh = rounded_block(size, radius, 0.01)
    rng = np.random.default_rng(0)
    grad = 1e-3 * rng.standard_normal((3, 3))
    u = mesh.points @ grad.T
    f = np.zeros_like(u)
    for kind, cells in mesh.cells.items():
        kl = solid_reference_data(mesh.points, cells, kind, MATERIAL).kl
        ue = u[cells].reshape(len(cells), -1)
        fe = np.einsum("mij,mj->mi", kl, ue).reshape(len(cells), -1, 3)
        np.add.at(f, cells, fe)
    outer = np.unique(np.concatenate([np.array(x) for x in _solid_boundary_faces(
        list(mesh.cells.values()))]))  # fmt: skip
    inner = np.setdiff1d(np.arange(len(mesh.points)), outer)
    assert inner.size > 0
    scale = np.abs(f).max()
    assert np.abs(f[inner]).max() < 1e-9 * scale
    np.testing.assert_allclose(f.sum(axis=0), 0.0, atol=1e-9 * scale)  # no net force


def test_rounded_nodes_are_the_edges_and_corners():
    size, radius = PB
    mesh = rounded_block(size, radius, 0.01, centre=(0.1, -0.2, 0.3))
    q = mesh.points - (0.1, -0.2, 0.3)
    a = _inner(size, radius)
    d = np.linalg.norm(q - np.clip(q, -a, a), axis=1)
    on_surface = np.isclose(d, radius, rtol=1e-9)
    assert np.all(on_surface[mesh.rounded])
    # the flat core's rim (mid-plane, beyond the inner rectangle) is in, the faces are out
    rim = on_surface & np.isclose(q[:, 2], 0.0, atol=1e-12)
    assert rim.any() and np.all(mesh.rounded[rim])
    face = on_surface & (np.abs(q[:, 0]) < a[0] - 1e-9) & (np.abs(q[:, 1]) < a[1] - 1e-9)
    assert face.any() and not mesh.rounded[face].any()
    # the tangent lines where the faces meet the rounding are in
    tangent = on_surface & np.isclose(np.abs(q[:, 0]), a[0]) & (np.abs(q[:, 2]) > 0.0)
    assert tangent.any() and np.all(mesh.rounded[tangent])
    # the corners' points beyond the inner box in x and y are in, at each of the four
    # corners of the flat core (at n_t = 2 one point each, on the mid-plane)
    corner = on_surface & (np.abs(q[:, 0]) > a[0] + 1e-9) & (np.abs(q[:, 1]) > a[1] + 1e-9)
    assert np.all(mesh.rounded[corner])
    quadrants = {(bool(x > 0), bool(y > 0)) for x, y in q[corner, :2]}
    assert len(quadrants) == 4


@pytest.mark.parametrize(
    ("args", "match"),
    [
        (((0.3, 0.2, 0.02), 0.011, 0.01), r"edge radius must lie in \(0, 0.01\] m"),
        (((0.3, 0.2, 0.02), 0.0, 0.01), "edge radius must lie in"),
        (((0.3, -0.2, 0.02), 0.005, 0.01), "size must be three lengths > 0 m"),
        (((0.3, 0.2, 0.02), 0.005, 0.0), "element size must be > 0 m"),
    ],
)
def test_bad_input_names_the_field(args, match):
    with pytest.raises(ValueError, match=match):
        rounded_block(*args)


def test_mixed_block_through_the_model_falls_and_rests_on_the_ground():
    # the rounded block (hex8, wedge6, tet4 on one node set) as a model: one node per mesh
    # point, 3 DOFs each, the mass of density x volume; dropped 5 mm it lands and rests on
    # the plane within its contact penetration (as the hex block of test_solids_model)
    import flexparcel as fp
    from flexparcel.contact.law import REFERENCE_AREA, ContactLaw

    mesh = rounded_block((0.1, 0.06, 0.02), 0.01, 0.01, centre=(0.0, 0.0, 0.015))
    b = fp.ModelBuilder()
    mat = SolidMaterial(1e5, 0.3, 1000.0, damping_ratio=1e-3)
    ids = b.add_solid_mesh(mesh.points, mesh.cells, material=mat)
    assert ids.size == len(mesh.points)
    law = ContactLaw.from_point_values(
        REFERENCE_AREA, stiffness=1e4, damping=2.0, damping_option="indentation",
        indentation_exponent=0.0, mu_static=0.3, mu_dynamic=0.3,
    )  # fmt: skip
    b.add_contact(ids, b.add_plane((0, 0, 0), (0, 0, 1)), law)
    model = b.finalize()
    assert model.dof_count == 3 * ids.size
    vol = sum(float(solid_reference_data(mesh.points, c, k, mat).volume.sum())
              for k, c in mesh.cells.items())  # fmt: skip
    np.testing.assert_allclose(model.mass[ids, 0].sum(), 1000.0 * vol, rtol=1e-12)
    r = fp.simulate(model, 0.2, dt_out=0.01)
    z = r.positions[:, ids, 2]
    assert np.all(np.isfinite(z))
    assert -1e-4 < z[-1].min() < 1e-4  # resting on the plane
    assert np.abs(r.velocities[-1, ids, :3]).max() < 0.02


def test_a_mesh_of_several_kinds_is_added_with_its_kinds_named():
    import flexparcel as fp

    mesh = rounded_block((0.1, 0.06, 0.02), 0.01, 0.02)
    b = fp.ModelBuilder()
    with pytest.raises(ValueError, match="give kind only with one array of cells"):
        b.add_solid_mesh(mesh.points, mesh.cells, "hex8", material=MATERIAL)
    with pytest.raises(ValueError, match="kind is needed with one array of cells"):
        b.add_solid_mesh(mesh.points, mesh.cells["hex8"], material=MATERIAL)
    with pytest.raises(ValueError, match="unknown solid element kind 'prism'"):
        b.add_solid_mesh(mesh.points, {"prism": mesh.cells["wedge6"]}, material=MATERIAL)
