"""ParaView export: one VTU file per output time plus a ``.pvd`` collection (via meshio), and
the description of a scene's parts that the export and the browser viewer share.

Series a scenario writes into ``DIR/paraview/`` (:func:`write_scene_paraview`; open the
``.pvd`` files together and press Play):

* the consignments (``packaging.pvd`` for a swing or drop test, ``conveyor.pvd`` for the
  conveyor): packaging shells and flexible (solid) contents. Point data:
  ``displacement_m`` (from the stress-free reference mesh), ``rotation_vector_rad``,
  ``velocity_m_per_s``, ``consignment_id`` (0, 1, ... in the order of the results'
  ``parts``), ``part`` (0 packaging, 1 content), ``node_id`` (the model's node number) and,
  where the run records it, ``contact_force_N`` (the conveyor: each packaging node's
  deflector normal force). Cell data: ``strain_max_principal_m_per_m`` and
  ``strain_min_principal_m_per_m`` (Green-Lagrange; shells: the membrane strain of the
  deformed against the reference cell, in its plane; solids: the 3-D strain at the cell
  centre), ``von_mises_stress_Pa`` (shells: the plane-stress membrane stress of the
  packaging's E and nu; solids: the St. Venant-Kirchhoff stress of the content's E and nu),
  ``consignment_id`` and ``part``;
* rigid contents (``content.pvd`` / ``contents.pvd``): each content's rounded box tessellated
  with its real edge radius (triangles), with ``consignment_id``, ``part`` and
  ``velocity_m_per_s`` (rigid-body velocity at each vertex);
* ``deflectors.pvd`` (conveyor): the deflector sheets' mid-plane meshes, fixed;
* ``belt.pvd`` (conveyor): the belt surface with ``velocity_m_per_s`` (the belt speed);
  ``plate.pvd`` (drop tests): the rigid plate under the consignment.

The parts (:func:`scene_parts`) are stored in ``results.npz``'s metadata under ``parts``: per
consignment its packaging and content node ids (as ``[start, stop)`` ranges), the rigid
content's node, inner half sizes and edge radius, and the materials; the belt, the deflector
nodes and the drop plate. :func:`parts_from_meta` reads them back.

Every VTU and PVD file is written atomically (a temporary file in the same folder, then
``os.replace``), so ParaView never opens half a file of a run in progress or killed.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any
from xml.sax.saxutils import quoteattr

import numpy as np

__all__ = [
    "PARTS_VERSION",
    "write_paraview",
    "write_paraview_boxes",
    "write_paraview_static",
    "write_scene_paraview",
    "scene_parts",
    "consignment_part",
    "parts_from_meta",
    "node_ranges",
    "belt_spans",
    "ranges_to_ids",
    "rounded_box_mesh",
    "cell_strain_stress",
    "rigid_content_frames",
]

PARTS_VERSION = 1
"""Version of the ``parts`` description in a results file's metadata."""

PACKAGING, CONTENT = 0, 1
"""Values of the ``part`` field."""


# --------------------------------------------------------------------------- parts
def node_ranges(ids) -> list[list[int]]:
    """Sorted unique node ids as ``[start, stop)`` ranges (a mesh's ids are mostly one run)."""
    ids = np.unique(np.asarray(ids, dtype=np.int64).ravel())
    if ids.size == 0:
        return []
    breaks = np.flatnonzero(np.diff(ids) != 1)
    starts = np.concatenate([[ids[0]], ids[breaks + 1]])
    stops = np.concatenate([ids[breaks], [ids[-1]]]) + 1
    return [[int(a), int(b)] for a, b in zip(starts, stops, strict=True)]


def ranges_to_ids(ranges) -> np.ndarray:
    """The node ids of :func:`node_ranges`' ranges, shape (m,)."""
    if not ranges:
        return np.zeros(0, np.int64)
    return np.concatenate([np.arange(int(a), int(b), dtype=np.int64) for a, b in ranges])


def consignment_part(
    name: str,
    consignment: Any,
    model: Any,
    content_material: Mapping[str, float] | None = None,
) -> dict:
    """JSON-ready description of one consignment of ``model``
    (a :class:`~flexparcel.consignments.build.Consignment`): node ranges, rigid content shape
    (from the model's rigid-body data: the real inner half sizes and edge radius) and the
    materials (packaging E [Pa], nu, thickness [m]; ``content_material``: the flexible
    content's ``youngs_modulus`` [Pa] and ``poisson_ratio``)."""
    build = consignment.build
    mat = build.material
    body = consignment.content_body
    out: dict[str, Any] = {
        "name": str(name),
        "consignment": str(build.spec.id),
        "packaging": node_ranges(consignment.packaging),
        "content_kind": "rigid" if body is not None else "flexible",
        "content": [] if body is not None else node_ranges(consignment.content_nodes),
        "content_body": None if body is None else int(body),
        "packaging_material": {
            "youngs_modulus_Pa": float(mat.youngs_modulus),
            "poisson_ratio": float(mat.poisson_ratio),
            "thickness_m": float(mat.thickness),
        },
        "content_material": None,
    }
    if body is not None:
        out["content_half_inner_m"] = [float(v) for v in model.box_half_by_node[body]]
        out["content_edge_radius_m"] = float(model.box_radius_by_node[body])
    elif content_material is not None:
        out["content_material"] = {
            "youngs_modulus_Pa": float(content_material["youngs_modulus"]),
            "poisson_ratio": float(content_material["poisson_ratio"]),
        }
    return out


def scene_parts(
    model: Any,
    consignments: Mapping[str, Any],
    *,
    content_material: Mapping[str, float] | None = None,
    belt: Mapping[str, float] | None = None,
    deflectors: Sequence[Any] = (),
    deflector_thickness: float | None = None,
    plate_z: float | None = None,
) -> dict:
    """The ``parts`` metadata of a results file (see the module docstring): ``consignments``
    (name -> consignment, in order), ``belt`` (``length_m``, ``width_m``, ``speed_m_s``; the
    belt lies at z = 0 from x = 0 to its length, centred on y = 0; with a transfer also
    ``transfer_gap_m``, ``transfer_length_m``, ``transfer_speed_m_s``), ``deflectors`` (node ids
    of each deflector's mid-plane mesh), ``plate_z`` (a drop test's rigid plate)."""
    return {
        "version": PARTS_VERSION,
        "consignments": [
            consignment_part(k, c, model, content_material) for k, c in consignments.items()
        ],
        "belt": None if belt is None else {k: float(v) for k, v in belt.items()},
        "deflectors": [node_ranges(d) for d in deflectors],
        "deflector_thickness_m": None
        if deflector_thickness is None
        else float(deflector_thickness),  # fmt: skip
        "plate_z_m": None if plate_z is None else float(plate_z),
    }


def parts_from_meta(meta: Mapping, node_count: int) -> dict | None:
    """The ``parts`` of a results file's metadata, or None when it has none. Files written
    before the parts were recorded: the conveyor's ``consignments`` (name -> node ids) give
    the consignments (all as packaging) and the other nodes the deflectors; a test's file
    gives nothing (None)."""
    parts = meta.get("parts")
    if isinstance(parts, Mapping) and parts.get("version") == PARTS_VERSION:
        return dict(parts)
    cons = meta.get("consignments")
    if meta.get("scenario") == "conveyor" and isinstance(cons, Mapping):
        used = np.zeros(node_count, bool)
        out = []
        for name, ids in cons.items():
            ids = np.asarray(ids, np.int64)
            used[ids] = True
            out.append({"name": str(name), "consignment": str(name),
                        "packaging": node_ranges(ids), "content_kind": "unknown",
                        "content": [], "content_body": None, "packaging_material": None,
                        "content_material": None})  # fmt: skip
        conveyor = meta.get("layout", {}).get("conveyor", {})
        belt = None
        if conveyor:  # keys with their unit since the layout carried them, plain before

            def key(name: str, unit: str) -> float:
                return float(conveyor.get(f"{name}_{unit}", conveyor.get(name)))

            belt = {"length_m": key("belt_length", "m"), "width_m": key("belt_width", "m"),
                    "speed_m_s": key("belt_speed", "m_s")}  # fmt: skip
        return {"version": PARTS_VERSION, "consignments": out, "belt": belt,
                "deflectors": [node_ranges(np.flatnonzero(~used))], "deflector_thickness_m": None,
                "plate_z_m": None, "legacy": True}  # fmt: skip
    return None


# --------------------------------------------------------------------------- geometry
def rounded_box_mesh(half_inner, radius: float, segments: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """Triangles of a box with rounded edges and corners: inner half sizes ``half_inner``
    [m] (3,), edge radius ``radius`` [m], ``segments`` per quarter circle. Returns points
    (v, 3) and triangles (t, 3), outward counter-clockwise; the flat faces are exact (the
    extent is 2 (half_inner + radius)). Seams between the six patches repeat their points."""
    h = np.asarray(half_inner, float).reshape(3)
    r = float(radius)
    m = max(1, int(segments))
    t = np.linspace(0.0, 1.0, m + 1)
    # each patch axis: the quarter circle on the negative side, the flat part (a zero-width
    # step from -0 to +0), the quarter circle on the positive side
    u = np.concatenate([-t[::-1], t])
    side = np.concatenate([-np.ones(m + 1), np.ones(m + 1)])
    n = u.size
    pts, tris = [], []
    for axis in range(3):
        a, b = (axis + 1) % 3, (axis + 2) % 3
        for sign in (-1.0, 1.0):
            uu, vv = np.meshgrid(u, u, indexing="ij")
            su, sv = np.meshgrid(side, side, indexing="ij")
            d = np.zeros((n, n, 3))
            d[..., axis] = sign
            # an angle-uniform cube-to-sphere map: tan of a quarter of pi per unit
            d[..., a] = np.tan(0.25 * np.pi * uu)
            d[..., b] = np.tan(0.25 * np.pi * vv)
            d /= np.linalg.norm(d, axis=-1, keepdims=True)
            s = np.zeros((n, n, 3))
            s[..., axis] = sign
            s[..., a] = su
            s[..., b] = sv
            p = s * h + r * d
            base = sum(len(q) for q in pts)
            pts.append(p.reshape(-1, 3))
            i, j = np.meshgrid(np.arange(n - 1), np.arange(n - 1), indexing="ij")
            v0 = (i * n + j).ravel() + base
            quad = np.column_stack([v0, v0 + n, v0 + n + 1, v0 + 1])
            tri = np.vstack([quad[:, [0, 1, 2]], quad[:, [0, 2, 3]]])
            # (a, b, axis) is right-handed: a x b = +axis, so (u, v) order faces outward on +
            tris.append(tri if sign > 0 else tri[:, [0, 2, 1]])
    return np.vstack(pts), np.vstack(tris).astype(np.int64)


def rigid_content_frames(
    positions: np.ndarray,
    rotation_vectors: np.ndarray,
    velocities: np.ndarray,
    body: int,
    half_inner,
    radius: float,
    segments: int = 3,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A rigid content's tessellated rounded box over the frames: points (k, v, 3) [m],
    triangles (t, 3) and vertex velocities v + omega x r (k, v, 3) [m/s] (omega spatial)."""
    from scipy.spatial.transform import Rotation

    local, tris = rounded_box_mesh(half_inner, radius, segments)
    rot = Rotation.from_rotvec(np.asarray(rotation_vectors)[:, body]).as_matrix()  # (k, 3, 3)
    arm = np.einsum("kij,vj->kvi", rot, local)
    centre = np.asarray(positions)[:, body]
    vel = np.asarray(velocities)[:, body]
    pts = centre[:, None, :] + arm
    v = vel[:, None, :3] + np.cross(vel[:, None, 3:6], arm)
    return pts, tris, v


# --------------------------------------------------------------------------- strain, stress
def _principal_2d(e11, e22, e12):
    mean = 0.5 * (e11 + e22)
    rad = np.sqrt((0.5 * (e11 - e22)) ** 2 + e12**2)
    return mean + rad, mean - rad


def _membrane_strain(ref: np.ndarray, cur: np.ndarray, conn: np.ndarray) -> np.ndarray:
    """Green-Lagrange membrane strain (e11, e22, e12) in each cell's reference plane frame,
    shape (m, 3); triangles from their edges, quads at their centre."""
    x0, x = ref[conn], cur[conn]
    if conn.shape[1] == 3:
        A = np.stack([x0[:, 1] - x0[:, 0], x0[:, 2] - x0[:, 0]], axis=1)  # (m, 2, 3)
        a = np.stack([x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]], axis=1)
    else:  # bilinear quad: tangents at the centre
        A = 0.5 * np.stack([x0[:, 1] + x0[:, 2] - x0[:, 0] - x0[:, 3],
                            x0[:, 2] + x0[:, 3] - x0[:, 0] - x0[:, 1]], axis=1)  # fmt: skip
        a = 0.5 * np.stack([x[:, 1] + x[:, 2] - x[:, 0] - x[:, 3],
                            x[:, 2] + x[:, 3] - x[:, 0] - x[:, 1]], axis=1)  # fmt: skip
    G = np.einsum("mai,mbi->mab", A, A)
    g = np.einsum("mai,mbi->mab", a, a)
    E_cov = 0.5 * (g - G)
    # orthonormal reference frame e1 along A1, e2 in the plane; J[i, a] = e_i . A_a
    e1 = A[:, 0] / np.linalg.norm(A[:, 0], axis=1, keepdims=True)
    n = np.cross(A[:, 0], A[:, 1])
    e2 = np.cross(n, e1)
    e2 /= np.linalg.norm(e2, axis=1, keepdims=True)
    J = np.stack([np.einsum("mi,mai->ma", e1, A), np.einsum("mi,mai->ma", e2, A)], axis=1)
    Jinv = np.linalg.inv(J)  # (m, 2, 2): A_a = J_ia e_i -> E_ij = Jinv_ai E_ab Jinv_bj
    E = np.einsum("mai,mab,mbj->mij", Jinv, E_cov, Jinv)
    return np.stack([E[:, 0, 0], E[:, 1, 1], E[:, 0, 1]], axis=1)


_HEX_XI = np.array([[-1, -1, -1], [1, -1, -1], [1, 1, -1], [-1, 1, -1],
                    [-1, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1]], float)  # fmt: skip


# wedge (triangle 0-1-2 at t = -1, 3-4-5 at t = +1): dN/d(r, s, t) at its centre (1/3, 1/3, 0).
# Written out here, as the hex's and tet's are, and not taken from elements.solid's shape
# functions: io is read by the calibration and selection toolkits, which must load no FE
# code (tests/test_layering.py); tests/test_paraview_export.py checks it against the hex.
_WEDGE_CENTRE_DN = np.array(
    [[-0.5, -0.5, -1 / 6], [0.5, 0.0, -1 / 6], [0.0, 0.5, -1 / 6],
     [-0.5, -0.5, 1 / 6], [0.5, 0.0, 1 / 6], [0.0, 0.5, 1 / 6]]
)  # fmt: skip


def _solid_strain(ref: np.ndarray, cur: np.ndarray, conn: np.ndarray) -> np.ndarray | None:
    """Green-Lagrange strain tensor at each solid cell's centre (m, 3, 3); hexahedra (VTK
    order), wedges and tetrahedra; None for other kinds."""
    if conn.shape[1] == 8:
        dN = _HEX_XI / 8.0  # derivatives of the trilinear shape functions at the centre
    elif conn.shape[1] == 6:
        dN = _WEDGE_CENTRE_DN
    elif conn.shape[1] == 4:
        dN = np.array([[-1, -1, -1], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
    else:
        return None
    Jx0 = np.einsum("mki,kj->mij", ref[conn], dN)
    Jx = np.einsum("mki,kj->mij", cur[conn], dN)
    F = Jx @ np.linalg.inv(Jx0)
    return 0.5 * (np.einsum("mki,mkj->mij", F, F) - np.eye(3))


def cell_strain_stress(
    ref: np.ndarray,
    cur: np.ndarray,
    ctype: str,
    conn: np.ndarray,
    youngs_modulus: np.ndarray | float | None = None,
    poisson_ratio: np.ndarray | float | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per cell of one block: max and min principal Green-Lagrange strain [-] and the von
    Mises stress [Pa] (NaN where E or nu is not given, or for a cell kind without a measure).
    Shells (``triangle``, ``quad``): membrane strain, plane-stress membrane stress;
    solids (``hexahedron``, ``wedge``, ``tetra``): St. Venant-Kirchhoff stress."""
    conn = np.asarray(conn, np.int64)
    m = len(conn)
    nan = np.full(m, np.nan)
    E = None if youngs_modulus is None else np.broadcast_to(np.asarray(youngs_modulus, float), (m,))
    nu = None if poisson_ratio is None else np.broadcast_to(np.asarray(poisson_ratio, float), (m,))
    if m == 0:
        return nan, nan, nan
    with np.errstate(invalid="ignore", divide="ignore"):
        if ctype in ("triangle", "quad"):
            e = _membrane_strain(ref, cur, conn)
            emax, emin = _principal_2d(e[:, 0], e[:, 1], e[:, 2])
            if E is None or nu is None:
                return emax, emin, nan
            c = E / (1.0 - nu**2)
            s11 = c * (e[:, 0] + nu * e[:, 1])
            s22 = c * (e[:, 1] + nu * e[:, 0])
            s12 = c * (1.0 - nu) * e[:, 2]  # G 2 e12 = E / (2 (1 + nu)) 2 e12
            vm = np.sqrt(s11**2 - s11 * s22 + s22**2 + 3.0 * s12**2)
            return emax, emin, vm
        if ctype in ("hexahedron", "wedge", "tetra"):
            Egl = _solid_strain(ref, cur, conn)
            w = np.linalg.eigvalsh(Egl)
            if E is None or nu is None:
                return w[:, -1], w[:, 0], nan
            lam = E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu))
            mu = E / (2.0 * (1.0 + nu))
            tr = np.trace(Egl, axis1=1, axis2=2)
            S = lam[:, None, None] * tr[:, None, None] * np.eye(3) + 2.0 * mu[:, None, None] * Egl
            dev = S - np.trace(S, axis1=1, axis2=2)[:, None, None] * np.eye(3) / 3.0
            vm = np.sqrt(1.5 * np.einsum("mij,mij->m", dev, dev))
            return w[:, -1], w[:, 0], vm
    return nan, nan, nan


# --------------------------------------------------------------------------- writers
def _consignment_cells(parts: Mapping, node_count: int, cells) -> tuple[list, dict]:
    """The cells of the consignments (packaging shells, solid contents) and per-node
    ``consignment_id`` / ``part`` arrays (-1 / -1 elsewhere) plus per-node E and nu of the
    packaging or content they belong to (NaN where not known)."""
    cid = np.full(node_count, -1, np.int64)
    part = np.full(node_count, -1, np.int64)
    E = np.full(node_count, np.nan)
    nu = np.full(node_count, np.nan)
    for i, c in enumerate(parts["consignments"]):
        for key, value, mat in (("packaging", PACKAGING, c.get("packaging_material")),
                                ("content", CONTENT, c.get("content_material"))):  # fmt: skip
            ids = ranges_to_ids(c.get(key, []))
            ids = ids[ids < node_count]
            cid[ids], part[ids] = i, value
            if mat:
                E[ids], nu[ids] = mat["youngs_modulus_Pa"], mat["poisson_ratio"]
    kept = []
    for ctype, conn in cells:
        conn = np.asarray(conn, np.int64)
        keep = (cid[conn] >= 0).all(axis=1)
        if keep.any():
            kept.append((ctype, conn[keep]))
    return kept, {"consignment_id": cid, "part": part, "E": E, "nu": nu}


def write_paraview(
    directory: str | Path,
    result,
    model,
    name: str = "shell",
    every: int = 1,
    *,
    parts: Mapping | None = None,
    contact_force: np.ndarray | None = None,
) -> Path:
    """Write ``DIR/name_XXXX.vtu`` and ``DIR/name.pvd``; open the ``.pvd`` in ParaView.

    Point data: ``displacement_m`` (from the model's reference positions),
    ``rotation_vector_rad``, ``velocity_m_per_s``, ``node_id``; cell data:
    ``strain_max_principal_m_per_m``, ``strain_min_principal_m_per_m`` (Green-Lagrange,
    see :func:`cell_strain_stress`). With ``parts`` (:func:`scene_parts`): only the
    consignments' cells and nodes (the belt and deflectors go to their own series, see
    :func:`write_scene_paraview`), plus ``consignment_id``, ``part`` (point and cell data),
    ``von_mises_stress_Pa`` from the parts' materials, and ``contact_force_N`` where
    ``contact_force`` [N] (k, n, 3) is given.
    """
    import meshio

    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    ref = np.asarray(model.positions0, float)
    n = len(ref)
    cells = [(ctype, np.asarray(conn, np.int64)) for ctype, conn in model.cells]
    extra: dict[str, np.ndarray] = {}
    if parts is not None:
        cells, extra = _consignment_cells(parts, n, cells)
        nodes = np.unique(np.concatenate([c.ravel() for _, c in cells])) if cells else (
            np.zeros(0, np.int64))  # fmt: skip
    else:
        nodes = np.arange(n)
    index = np.full(n, -1, np.int64)
    index[nodes] = np.arange(nodes.size)
    local_cells = [(ctype, index[conn]) for ctype, conn in cells]
    entries = []
    for k in range(0, len(result.time), max(1, int(every))):
        pos = np.asarray(result.positions[k], float)
        point_data = {
            "displacement_m": (pos - ref)[nodes],
            "rotation_vector_rad": np.asarray(result.rotation_vectors[k])[nodes],
            "velocity_m_per_s": np.asarray(result.velocities[k])[nodes, :3],
            "node_id": nodes,
        }
        cell_data: dict[str, list] = {"strain_max_principal_m_per_m": [],
                                      "strain_min_principal_m_per_m": []}  # fmt: skip
        if parts is not None:
            point_data["consignment_id"] = extra["consignment_id"][nodes]
            point_data["part"] = extra["part"][nodes]
            if contact_force is not None:
                point_data["contact_force_N"] = np.asarray(contact_force[k])[nodes]
            for key in ("von_mises_stress_Pa", "consignment_id", "part"):
                cell_data[key] = []
        for ctype, conn in cells:
            first = conn[:, 0]
            E = extra["E"][first] if parts is not None else None
            nu = extra["nu"][first] if parts is not None else None
            emax, emin, vm = cell_strain_stress(ref, pos, ctype, conn, E, nu)
            cell_data["strain_max_principal_m_per_m"].append(emax)
            cell_data["strain_min_principal_m_per_m"].append(emin)
            if parts is not None:
                cell_data["von_mises_stress_Pa"].append(vm)
                cell_data["consignment_id"].append(extra["consignment_id"][first])
                cell_data["part"].append(extra["part"][first])
        fname = f"{name}_{k:04d}.vtu"
        mesh = meshio.Mesh(pos[nodes], local_cells, point_data=point_data,
                           cell_data=cell_data if local_cells else None)  # fmt: skip
        _write_vtu(directory / fname, mesh)
        entries.append((float(result.time[k]), fname))
    return _write_pvd(directory / f"{name}.pvd", entries)


def write_paraview_boxes(
    directory: str | Path,
    time,
    centres,
    rotations,
    sizes,
    name: str = "content",
    *,
    edge_radius: Sequence[float] | None = None,
    velocities=None,
    consignment_ids: Sequence[int] | None = None,
    segments: int = 3,
) -> Path:
    """Rigid boxes: ``DIR/name_XXXX.vtu`` and ``DIR/name.pvd``.

    ``time`` [s] (k,); ``centres`` [m] (k, b, 3); ``rotations`` body -> world (k, b, 3, 3);
    ``sizes`` outer edge lengths [m] along the body axes (b, 3). Without ``edge_radius`` each
    box is one hexahedron; with it (one radius [m] per box) each is its rounded box,
    tessellated (:func:`rounded_box_mesh`, ``segments`` per quarter circle). Point data:
    ``consignment_id`` (``consignment_ids``, default 0, 1, ...), ``part`` (1, content) and,
    with ``velocities`` (k, b, 6) [m/s, rad/s] (spatial angular velocity),
    ``velocity_m_per_s`` of each vertex. Rigid contents are a single node of the model,
    invisible in :func:`write_paraview`; this series shows them next to the packaging.
    """
    import meshio

    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    time = np.asarray(time, float)
    centres = np.asarray(centres, float)
    rotations = np.asarray(rotations, float)
    sizes = np.asarray(sizes, float).reshape(-1, 3)
    nb = sizes.shape[0]
    if centres.shape != (len(time), nb, 3) or rotations.shape != (len(time), nb, 3, 3):
        raise ValueError(
            f"write_paraview_boxes: centres {centres.shape} and rotations {rotations.shape} "
            f"must be ({len(time)}, {nb}, 3) and ({len(time)}, {nb}, 3, 3)"
        )
    ids = np.arange(nb) if consignment_ids is None else np.asarray(consignment_ids, np.int64)
    if edge_radius is None:
        # VTK hexahedron order: bottom face counter-clockwise, then the top face above it
        local = (0.5 * _HEX_XI)[None, :, :] * sizes[:, None, :]  # (b, 8, 3)
        cell_type, conn = "hexahedron", np.arange(8 * nb).reshape(nb, 8)
    else:
        radius = np.asarray(edge_radius, float).reshape(nb)
        pairs = zip(sizes, radius, strict=True)
        meshes = [rounded_box_mesh(0.5 * s - r, r, segments) for s, r in pairs]
        nv = len(meshes[0][0])
        local = np.stack([p for p, _ in meshes])  # (b, v, 3)
        cell_type = "triangle"
        conn = np.vstack([t + i * nv for i, (_, t) in enumerate(meshes)])
    nv = local.shape[1]
    entries = []
    for k, t in enumerate(time):
        arm = np.einsum("bij,bcj->bci", rotations[k], local)
        pts = centres[k][:, None, :] + arm
        point_data = {"consignment_id": np.repeat(ids, nv),
                      "part": np.full(nb * nv, CONTENT, np.int64)}  # fmt: skip
        if velocities is not None:
            v = np.asarray(velocities[k], float)  # (b, 6)
            point_data["velocity_m_per_s"] = (v[:, None, :3] + np.cross(v[:, None, 3:6], arm)
                                              ).reshape(-1, 3)  # fmt: skip
        fname = f"{name}_{k:04d}.vtu"
        _write_vtu(directory / fname, meshio.Mesh(pts.reshape(-1, 3), [(cell_type, conn)],
                                                  point_data=point_data))  # fmt: skip
        entries.append((float(t), fname))
    return _write_pvd(directory / f"{name}.pvd", entries)


def write_paraview_static(
    directory: str | Path,
    name: str,
    points: np.ndarray,
    cells: Sequence[tuple[str, np.ndarray]],
    point_data: Mapping[str, np.ndarray] | None = None,
    time: float = 0.0,
) -> Path:
    """A part that does not move (belt, deflectors, plate): ``DIR/name_0000.vtu`` and
    ``DIR/name.pvd`` with that one file (ParaView shows it at every time)."""
    import meshio

    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    fname = f"{name}_0000.vtu"
    _write_vtu(directory / fname, meshio.Mesh(np.asarray(points, float), list(cells),
                                              point_data=dict(point_data or {})))  # fmt: skip
    return _write_pvd(directory / f"{name}.pvd", [(float(time), fname)])


def belt_spans(belt: Mapping[str, float]) -> list[tuple[float, float, float]]:
    """``(x_start, x_end, speed)`` [m, m, m/s] of each belt of a results file's ``belt``
    part: the belt from x = 0, and a transfer belt after its gap where there is one."""
    length = belt["length_m"]
    spans = [(0.0, length, belt.get("speed_m_s", 0.0))]
    if "transfer_length_m" in belt:
        x0 = length + belt["transfer_gap_m"]
        spans.append((x0, x0 + belt["transfer_length_m"], belt["transfer_speed_m_s"]))
    return spans


def _static_parts(parts: Mapping, model, result) -> dict[str, tuple]:
    """name -> (points, cells, point_data) of the belt, deflectors and plate of ``parts``."""
    out: dict[str, tuple] = {}
    belt = parts.get("belt")
    if belt:
        w = belt["width_m"]
        spans = belt_spans(belt)
        corners = [((a, -w / 2), (b, -w / 2), (b, w / 2), (a, w / 2)) for a, b, _ in spans]
        pts = np.array([[x, y, 0.0] for quad in corners for x, y in quad])
        v = np.array([[speed, 0.0, 0.0] for _, _, speed in spans for _ in range(4)])
        quads = np.arange(4 * len(spans)).reshape(-1, 4)
        out["belt"] = (pts, [("quad", quads)], {"velocity_m_per_s": v})
    defl = [ranges_to_ids(d) for d in parts.get("deflectors", [])]
    if defl and any(d.size for d in defl):
        n = len(model.positions0)
        which = np.full(n, -1, np.int64)
        for i, d in enumerate(defl):
            which[d[d < n]] = i
        tri = [np.asarray(c, np.int64) for t, c in model.cells if t == "triangle"]
        tri = np.vstack(tri) if tri else np.zeros((0, 3), np.int64)
        tri = tri[(which[tri] >= 0).all(axis=1)]
        if len(tri):
            nodes = np.unique(tri)
            index = np.full(n, -1, np.int64)
            index[nodes] = np.arange(nodes.size)
            pts = np.asarray(result.positions[0])[nodes]
            out["deflectors"] = (pts, [("triangle", index[tri])],
                                 {"deflector_id": which[nodes]})  # fmt: skip
    if parts.get("plate_z_m") is not None:
        z = float(parts["plate_z_m"])
        p = np.asarray(result.positions)
        lo, hi = p[..., :2].min(axis=(0, 1)), p[..., :2].max(axis=(0, 1))
        pad = 0.25 * float(np.max(hi - lo)) + 0.01
        lo, hi = lo - pad, hi + pad
        pts = np.array([[lo[0], lo[1], z], [hi[0], lo[1], z], [hi[0], hi[1], z],
                        [lo[0], hi[1], z]])  # fmt: skip
        out["plate"] = (pts, [("quad", np.array([[0, 1, 2, 3]]))], {})
    return out


def write_scene_paraview(
    directory: str | Path,
    result,
    model,
    parts: Mapping,
    *,
    name: str,
    content_name: str,
    contact_force: np.ndarray | None = None,
    every: int = 1,
) -> dict[str, Path]:
    """Every series of a scenario's run (module docstring): ``name`` (the consignments),
    ``content_name`` (rigid contents, rounded boxes), and the static ``belt``,
    ``deflectors`` and ``plate`` where the parts have them. Returns file key -> ``.pvd``
    (``paraview``, ``paraview_content``, ``paraview_belt``, ...)."""
    directory = Path(directory)
    files = {"paraview": write_paraview(directory, result, model, name=name, every=every,
                                        parts=parts, contact_force=contact_force)}  # fmt: skip
    rigid = [
        (i, c) for i, c in enumerate(parts["consignments"]) if c.get("content_body") is not None
    ]
    if rigid:
        from scipy.spatial.transform import Rotation

        ks = np.arange(0, len(result.time), max(1, int(every)))
        bodies = [c["content_body"] for _, c in rigid]
        rv = np.asarray(result.rotation_vectors)[ks][:, bodies]
        rot = Rotation.from_rotvec(rv.reshape(-1, 3)).as_matrix().reshape(*rv.shape[:2], 3, 3)
        sizes = [2.0 * (np.asarray(c["content_half_inner_m"]) + c["content_edge_radius_m"])
                 for _, c in rigid]  # fmt: skip
        files[f"paraview_{content_name}"] = write_paraview_boxes(
            directory, np.asarray(result.time)[ks], np.asarray(result.positions)[ks][:, bodies],
            rot, sizes, name=content_name,
            edge_radius=[c["content_edge_radius_m"] for _, c in rigid],
            velocities=np.asarray(result.velocities)[ks][:, bodies],
            consignment_ids=[i for i, _ in rigid],
        )  # fmt: skip
    for key, (pts, cells, pdata) in _static_parts(parts, model, result).items():
        files[f"paraview_{key}"] = write_paraview_static(directory, key, pts, cells, pdata,
                                                         float(result.time[0]))  # fmt: skip
    return files


def _write_vtu(path: Path, mesh) -> Path:
    """``mesh`` (a meshio.Mesh) as binary VTU at ``path``, atomically: ParaView opening a
    run in progress, or a run killed mid-write, never meets half a file."""
    import meshio

    from flexparcel.io.atomic import atomic_path

    with atomic_path(path) as tmp:
        meshio.write(tmp, mesh, file_format="vtu", binary=True)
    return path


def _write_pvd(pvd: Path, entries: list[tuple[float, str]]) -> Path:
    """A ParaView collection file listing ``(time, file)`` entries, written atomically."""
    from flexparcel.io.atomic import write_atomic

    lines = [
        '<?xml version="1.0"?>',
        '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">',
        "  <Collection>",
    ]
    lines += [
        f'    <DataSet timestep="{t!r}" group="" part="0" file={quoteattr(f)}/>' for t, f in entries
    ]
    lines += ["  </Collection>", "</VTKFile>", ""]
    return write_atomic(pvd, "\n".join(lines))
