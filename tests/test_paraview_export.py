"""ParaView output (flexparcel.io.paraview): the series a scenario writes, their fields with
units in the names, the rigid contents' rounded boxes, the belt and deflectors as their own
series, and the strain and stress measures checked on cells with known answers."""

from __future__ import annotations

from pathlib import Path

import meshio
import numpy as np
import pytest

from raw_snapshots import SMALL, raw_snapshot

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "examples" / "conveyor_scene.toml"


# --------------------------------------------------------------------------- measures
def test_membrane_strain_of_a_stretched_and_turned_quad_and_triangle():
    from scipy.spatial.transform import Rotation

    from flexparcel.io.paraview import cell_strain_stress

    ref = np.array([[0, 0, 0], [2, 0, 0], [2, 1, 0], [0, 1, 0]], float)
    lam = 1.1
    turn = Rotation.from_rotvec([0.3, -0.7, 0.4]).as_matrix()
    cur = (ref * [lam, 1.0, 1.0]) @ turn.T + [0.5, 0.2, -1.0]
    E, nu = 2e9, 0.3
    e = 0.5 * (lam**2 - 1.0)
    s11, s22 = E / (1 - nu**2) * e, E / (1 - nu**2) * nu * e
    vm = np.sqrt(s11**2 - s11 * s22 + s22**2)
    for ctype, conn in (("quad", np.array([[0, 1, 2, 3]])), ("triangle", np.array([[0, 1, 2]]))):
        emax, emin, s = cell_strain_stress(ref, cur, ctype, conn, E, nu)
        assert emax[0] == pytest.approx(e) and emin[0] == pytest.approx(0.0, abs=1e-12)
        assert s[0] == pytest.approx(vm)
        # a rigid motion strains nothing
        emax, emin, s = cell_strain_stress(ref, ref @ turn.T + 3.0, ctype, conn, E, nu)
        assert max(abs(emax[0]), abs(emin[0]), s[0] / E) < 1e-12
    # shear in the plane: principal strains +-, equal and opposite
    sheared = ref + np.outer(ref[:, 1], [0.05, 0, 0])
    emax, emin, _ = cell_strain_stress(ref, sheared, "quad", np.array([[0, 1, 2, 3]]))
    assert emax[0] > 0 > emin[0]


def test_solid_strain_and_stress_of_a_stretched_hexahedron():
    from flexparcel.io.paraview import cell_strain_stress

    cube = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0],
                     [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], float)  # fmt: skip
    conn = np.arange(8)[None]
    lam, E, nu = 1.05, 1e6, 0.25
    emax, emin, vm = cell_strain_stress(cube, cube * [1, 1, lam], "hexahedron", conn, E, nu)
    e = 0.5 * (lam**2 - 1)
    assert emax[0] == pytest.approx(e) and emin[0] == pytest.approx(0.0, abs=1e-12)
    # St. Venant-Kirchhoff, uniaxial strain: S33 = (lam + 2 mu) e, S11 = S22 = lam e
    la, mu = E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))
    assert vm[0] == pytest.approx(abs((la + 2 * mu) * e - la * e))
    tets = cell_strain_stress(cube, cube * 2.0, "tetra", np.array([[0, 1, 3, 4]]))[0]
    assert tets[0] == pytest.approx(1.5)  # (2^2 - 1) / 2
    # a wedge (half the cube) stretched along z, as the hexahedron: the same strains
    wedge = np.array([[0, 1, 3, 4, 5, 7]])
    w_max, w_min, w_vm = cell_strain_stress(cube, cube * [1, 1, lam], "wedge", wedge, E, nu)
    assert w_max[0] == pytest.approx(e) and w_min[0] == pytest.approx(0.0, abs=1e-12)
    assert w_vm[0] == pytest.approx(vm[0])


def test_rounded_box_has_the_real_size_and_rounded_corners():
    from flexparcel.io.paraview import rounded_box_mesh
    from flexparcel.model.rigid import RoundedBox

    box = RoundedBox(0.06, 0.045, 0.01, edge_radius=0.003, mass=0.03)
    pts, tri = rounded_box_mesh(box.half_inner, box.edge_radius, segments=4)
    assert np.allclose(np.ptp(pts, axis=0), [0.06, 0.045, 0.01])
    # outward triangles: the divergence theorem gives the volume, close to the exact one
    a, b, c = pts[tri[:, 0]], pts[tri[:, 1]], pts[tri[:, 2]]
    volume = np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0
    assert volume == pytest.approx(box.volume(), rel=5e-3)
    # no point at a sharp corner: each lies within the radius of the inner box
    gap = np.linalg.norm(np.maximum(np.abs(pts) - box.half_inner, 0.0), axis=1)
    assert gap.max() == pytest.approx(box.edge_radius)


def test_node_ranges_round_trip():
    from flexparcel.io.paraview import node_ranges, ranges_to_ids

    ids = np.array([7, 3, 4, 5, 10, 11, 3])
    assert node_ranges(ids) == [[3, 6], [7, 8], [10, 12]]
    assert ranges_to_ids(node_ranges(ids)).tolist() == [3, 4, 5, 7, 10, 11]
    assert node_ranges([]) == [] and ranges_to_ids([]).size == 0


# --------------------------------------------------------------------------- a drop test's files
@pytest.fixture(scope="module")
def drop_dir(tmp_path_factory):
    from flexparcel.consignments.userfile import load_consignment_file
    from flexparcel.scenarios.registry import get_scenario

    scenario = get_scenario("drop-horizontal")
    result = scenario.run(raw_snapshot(load_consignment_file(SMALL)), t_end=0.004)
    out = tmp_path_factory.mktemp("pv") / "drop"
    return out, scenario.write(result, out), result


def test_drop_writes_packaging_content_and_plate_series(drop_dir):
    out, files, result = drop_dir
    pv = out / "paraview"
    for name in ("packaging.pvd", "packaging_0000.vtu", "content.pvd", "content_0000.vtu",
                 "plate.pvd", "plate_0000.vtu"):  # fmt: skip
        assert (pv / name).is_file(), name
    assert files["paraview"] == pv / "packaging.pvd"
    assert files["paraview_content"] == pv / "content.pvd"
    assert files["paraview_plate"] == pv / "plate.pvd"
    k = len(result.simulation.time)
    assert (pv / "packaging.pvd").read_text().count("<DataSet") == k
    plate = meshio.read(pv / "plate_0000.vtu")
    assert np.allclose(plate.points[:, 2], 0.0)


def test_vtu_and_pvd_files_are_written_atomically(drop_dir, tmp_path, monkeypatch):
    # no temporary file is left next to a run's series; a writer that fails keeps the old
    # file whole (ParaView reading a run in progress never meets half a file)
    from flexparcel.io.paraview import write_paraview_static

    out, _, _ = drop_dir
    assert not [p.name for p in (out / "paraview").iterdir() if p.name.startswith(".")]
    pts = np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])
    quad = [("quad", np.array([[0, 1, 2, 3]]))]
    write_paraview_static(tmp_path, "belt", pts, quad)
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    assert set(before) == {"belt.pvd", "belt_0000.vtu"}

    def broken(path, *args, **kwargs):
        Path(path).write_bytes(b"<VTKFile half")  # a write cut short
        raise OSError("disk full")

    monkeypatch.setattr(meshio, "write", broken)
    with pytest.raises(OSError, match="disk full"):
        write_paraview_static(tmp_path, "belt", 2 * pts, quad)
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == before


def test_packaging_fields_carry_units_ids_strain_and_stress(drop_dir):
    from flexparcel.io.results import load_result

    out, _, result = drop_dir
    run = result.record
    c = run.consignment
    first = meshio.read(out / "paraview" / "packaging_0000.vtu")
    last = meshio.read(out / "paraview" / f"packaging_{len(result.simulation.time) - 1:04d}.vtu")
    for key in ("displacement_m", "rotation_vector_rad", "velocity_m_per_s", "consignment_id",
                "part", "node_id"):  # fmt: skip
        assert key in last.point_data, key
    assert "contact_force_N" not in last.point_data  # a drop records none
    # only the packaging's nodes (the rigid content's node is in the content series)
    assert sorted(last.point_data["node_id"]) == sorted(c.packaging.tolist())
    assert set(last.point_data["part"]) == {0} and set(last.point_data["consignment_id"]) == {0}
    nodes = last.point_data["node_id"]
    assert np.allclose(last.points, result.simulation.positions[-1][nodes])
    assert np.allclose(last.point_data["velocity_m_per_s"],
                       result.simulation.velocities[-1][nodes, :3])  # fmt: skip
    names = ("strain_max_principal_m_per_m", "strain_min_principal_m_per_m",
             "von_mises_stress_Pa", "consignment_id", "part")  # fmt: skip
    for key in names:
        assert key in last.cell_data, key
    # the raw mesh starts at its reference: no strain, no stress; it has deformed by the end
    assert np.abs(np.concatenate(first.cell_data["strain_max_principal_m_per_m"])).max() < 1e-12
    assert np.concatenate(first.cell_data["von_mises_stress_Pa"]).max() < 1e-3
    vm = np.concatenate(last.cell_data["von_mises_stress_Pa"])
    assert np.all(np.isfinite(vm)) and vm.max() > 0.0
    # the material is recorded with the results (60 MPa, nu 0.4: the example's overrides)
    parts = load_result(out / "results.npz")["meta"]["parts"]
    mat = parts["consignments"][0]["packaging_material"]
    assert mat["youngs_modulus_Pa"] == pytest.approx(60e6) and mat["poisson_ratio"] == 0.4
    assert parts["plate_z_m"] == 0.0 and parts["belt"] is None


def test_rigid_content_is_its_rounded_box(drop_dir):
    from scipy.spatial.transform import Rotation

    out, _, result = drop_dir
    c = result.record.consignment
    res = result.simulation
    k = len(res.time) - 1
    mesh = meshio.read(out / "paraview" / f"content_{k:04d}.vtu")
    assert mesh.cells[0].type == "triangle"
    rot = Rotation.from_rotvec(res.rotation_vectors[k, c.content_body]).as_matrix()
    local = (mesh.points - res.positions[k, c.content_body]) @ rot
    assert np.allclose(np.ptp(local, axis=0), c.content_box, atol=1e-9)
    assert set(mesh.point_data["part"]) == {1}
    v = mesh.point_data["velocity_m_per_s"]
    assert np.allclose(v.mean(axis=0), res.velocities[k, c.content_body, :3], atol=1e-3)


# --------------------------------------------------------------------------- the conveyor's files
@pytest.fixture(scope="module")
def conveyor_dir(tmp_path_factory):
    from flexparcel.consignments.userfile import load_consignment_file
    from flexparcel.scenarios.conveyor_scene import load_scene_file
    from flexparcel.scenarios.registry import get_scenario

    scene = load_scene_file(SCENE)
    snaps = {k: raw_snapshot(load_consignment_file(SCENE.parent / ref))
             for k, ref in scene.consignments.items()}  # fmt: skip
    scenario = get_scenario("conveyor", scene=scene, workers=0)
    result = scenario.run(snaps, t_end=0.002)
    out = tmp_path_factory.mktemp("pv") / "conveyor"
    return out, scenario.write(result, out), result


def test_conveyor_writes_belt_deflectors_and_contact_forces(conveyor_dir):
    out, files, result = conveyor_dir
    pv = out / "paraview"
    series = {"paraview": "conveyor", "paraview_contents": "contents", "paraview_belt": "belt",
              "paraview_deflectors": "deflectors"}  # fmt: skip
    for key, name in series.items():
        assert files[key] == pv / f"{name}.pvd" and (pv / f"{name}_0000.vtu").is_file(), key
    cm = result.record.conveyor_model
    belt = meshio.read(pv / "belt_0000.vtu")
    assert np.ptp(belt.points[:, 0]) == pytest.approx(cm.layout.conveyor.belt_length)
    assert np.allclose(belt.point_data["velocity_m_per_s"][:, 0], cm.layout.conveyor.belt_speed)
    defl = meshio.read(pv / "deflectors_0000.vtu")
    ids = np.concatenate(cm.parts.deflector_vertices)
    assert len(defl.points) == len(ids) and set(defl.point_data["deflector_id"]) == {0, 1}
    # the consignment series holds no deflector cell, and names its consignments 0 .. 3
    k = len(result.simulation.time) - 1
    cons = meshio.read(pv / f"conveyor_{k:04d}.vtu")
    assert not set(cons.point_data["node_id"]) & set(ids.tolist())
    assert set(cons.point_data["consignment_id"]) == {0, 1, 2, 3}
    force = cons.point_data["contact_force_N"]
    assert force.shape == (len(cons.points), 3)
    # contact_forces.npz: the same node forces, non-zero entries only
    with np.load(out / "contact_forces.npz") as z:
        assert set(z.files) == {"time", "frame", "node", "force_N"}
        mine = z["frame"] == k
        total = np.abs(z["force_N"][mine]).sum()
    assert total == pytest.approx(np.abs(force).sum())
    contents = meshio.read(pv / f"contents_{k:04d}.vtu")
    assert set(contents.point_data["consignment_id"]) == {0, 1, 2, 3}


def test_viewer_of_the_conveyor_shows_belt_deflectors_and_forces(conveyor_dir, tmp_path):
    from flexparcel.viz.viewer import load_scene, write_viewer

    out, _, _ = conveyor_dir
    scene = load_scene(out)
    assert [t["name"] for t in scene.static] == ["belt (1.6 m/s)", "deflectors"]
    assert "contact_force" not in scene.unavailable
    assert scene.consignments == ["a", "b", "c", "d"]
    text = write_viewer(out, tmp_path / "v.html").read_text(encoding="utf-8")
    assert '<option value="contact_force">' in text and "Conveyor, 4 consignments" in text


def _pushed_into_deflector(conveyor_dir, at_rest: bool = False):
    """The conveyor run with consignment a's last frame moved 0.5 h into deflector 0's face
    (h: half its packaging thickness), its velocities zeroed if ``at_rest``: (conveyor model,
    a, deflector 0, the changed result)."""
    from dataclasses import replace

    _, _, result = conveyor_dir
    cm, res = result.record.conveyor_model, result.simulation
    c, g = cm.consignments["a"], cm.parts.deflectors[0]
    h = c.contact_radius
    pos = np.array(res.positions)
    dist, on = g.over_face(pos[-1, c.packaging], below=h)
    assert on.any()
    pos[-1, c.node_ids] -= (dist[on].min() - 0.5 * h) * np.asarray(g.normal)
    vel = np.array(res.velocities)
    if at_rest:
        vel[:] = 0.0
    return cm, c, g, replace(res, positions=pos, velocities=vel)


def test_node_forces_add_up_to_the_consignment_deflector_force(conveyor_dir):
    # the short run has not reached the deflectors yet: push consignment a's last frame into
    # deflector 0 and compare the written per-node vectors with the law's normal forces
    from flexparcel.scenarios.conveyor_scenario import _deflector_node_forces
    from flexparcel.scenarios.conveyor_scene import deflector_node_forces

    cm, c, g, pushed = _pushed_into_deflector(conveyor_dir)
    node = _deflector_node_forces(cm, pushed)
    total = deflector_node_forces(cm, pushed).sum(axis=0)[:, c.packaging].sum(axis=1)
    assert total[-1] > 0.0 and np.all(total[:-1] == 0.0)
    assert (node[-1, c.packaging] @ g.normal).sum() == pytest.approx(total[-1])
    assert not node[-1, cm.consignments["b"].packaging].any()


def test_deflector_force_is_the_models_own_contact_force(conveyor_dir):
    """The recorded deflector force is what the model's node-face contact sets apply, in
    newtons: the per-area law times each node's tributary area (a force computed as the bare
    law was a pressure in Pa, 2,500 times the force of a 20 mm node)."""
    from flexparcel.model.interfaces import ContactContext, ContactOutput
    from flexparcel.model.model import State
    from flexparcel.scenarios.conveyor_scene import deflector_node_forces

    cm, c, g, pushed = _pushed_into_deflector(conveyor_dir, at_rest=True)  # the spring term
    recorded = deflector_node_forces(cm, pushed)[:, -1, c.packaging].sum()

    m = cm.model
    n = m.node_count
    rot = np.broadcast_to(np.eye(3), (n, 3, 3)).copy()
    state = State(float(pushed.time[-1]), pushed.positions[-1].copy(), rot,
                  pushed.velocities[-1].copy(), np.zeros((n, 6)))  # fmt: skip
    ctx = ContactContext(model=m, laws=m.contact_laws,
                         factors=np.array([sch(state.time) for sch in m.contact_schedules]),
                         node_mass=np.full(n, np.inf), impact_speed=np.inf, start=state,
                         step=1e-5, box_half=m.box_half_at(state.time))  # fmt: skip
    out = ContactOutput(np.zeros((n, 6)))
    for cs in m.contact_sets:
        if cs.kind == "node_face":  # packaging on deflector faces (and on other packaging)
            cs.prepare(ctx, state, 1e-5)
            cs.evaluate(ctx, state, out)
    applied = float(out.forces[c.packaging, :3].sum(axis=0) @ np.asarray(g.normal))
    assert applied > 0.1  # some newtons, a film pressed 0.5 h into the sheet
    assert recorded == pytest.approx(applied, rel=1e-9)


def test_viewer_opens_conveyor_results_written_without_parts(conveyor_dir, tmp_path):
    # results.npz of a run from before the parts were recorded: the consignments come from
    # the node lists of its metadata, the other nodes' cells are the deflectors
    import json

    from flexparcel.viz.viewer import load_scene

    out, _, _ = conveyor_dir
    with np.load(out / "results.npz") as z:
        arrays = {k: z[k] for k in z.files}
    meta = json.loads(str(arrays["meta_json"]))
    del meta["parts"]
    # and the layout's keys as they were then, without their unit
    conveyor = meta["layout"]["conveyor"]
    meta["layout"]["conveyor"] = {k.removesuffix("_m_s").removesuffix("_m"): v
                                  for k, v in conveyor.items()}  # fmt: skip
    assert "belt_length" in meta["layout"]["conveyor"]
    arrays["meta_json"] = np.array(json.dumps(meta))
    old = tmp_path / "old"
    old.mkdir()
    np.savez_compressed(old / "results.npz", **arrays)
    scene = load_scene(old)
    assert scene.consignments == ["a", "b", "c", "d"]
    assert [t["name"] for t in scene.static] == ["belt (1.6 m/s)", "deflectors"]
    assert [m.name for m in scene.dynamic] == ["packaging"]  # rigid contents unknown
    assert scene.unavailable["contact_force"].startswith("not in these results")


def test_belt_spans_of_a_transfer():
    from flexparcel.io.paraview import belt_spans

    belt = {"length_m": 3.0, "width_m": 0.6, "speed_m_s": 1.6}
    assert belt_spans(belt) == [(0.0, 3.0, 1.6)]
    belt.update(transfer_gap_m=0.02, transfer_length_m=1.0, transfer_speed_m_s=1.2)
    (a, b) = belt_spans(belt)
    assert a == (0.0, 3.0, 1.6) and b == pytest.approx((3.02, 4.02, 1.2))
