"""A 3-D viewer of a results folder in the browser: ``RESULTS_DIR/view.html``, one
self-contained HTML file (plotly.js embedded, nothing fetched when it is opened; it needs a
browser with WebGL).

It shows the packaging surfaces, the contents (rigid rounded boxes with their real edge
radius, or the boundary of a solid content mesh), the belt, the deflectors and a drop test's
plate in 3-D, animated over the saved frames: play/pause, a time slider, a camera turned by
dragging (scroll to zoom), see-through packaging, and colour by a chosen field:
displacement from the first frame [mm], speed [m/s], max principal membrane strain [%]
(Green-Lagrange, of each packaging cell against the stress-free mesh; a solid content's cells
their 3-D strain), the consignment, and the contact force [N] where the results carry it
(the conveyor's deflector normal force per packaging node, ``contact_forces.npz``). Fields
a results folder does not have are listed, greyed out, with the reason (no scenario records
contact pressures).

Written by :func:`write_viewer` (``flexparcel view RESULTS_DIR``) and, through the picture
writers of :mod:`flexparcel.viz.scenario_pictures` that the command line passes to every
scenario's ``write``, after every ``flexparcel run`` and ``flexparcel demo`` run (the
scenarios do not import this module: the caller hands it in, like the pictures).

Size. The page is the plotly.js bundle (4.8 MB, plotly 7.1) plus the frames: vertex
positions quantised to 16 bits over the moving parts' bounding box (3 m of travel: 0.05 mm
steps) and each animated field to 8 bits over its range, base64-encoded: about
``4/3 (6 V + F_v V + F_c C)`` bytes a frame for V vertices, C triangles, F_v vertex fields
(displacement, speed, and the contact force where there is one) and F_c cell fields (the
strain), some 13 bytes per vertex and frame. Measured (plotly 7.1): the small example
consignment (50 packaging vertices and its 216-vertex rounded box), drop test, 11 frames:
4.9 MB, +3.4 kB a frame; KP/BW at 25 mm (``flexparcel demo --quick``): swing, 51 frames,
5.1 MB; each drop, 151 frames, 5.6 MB; the four paper consignments at 25 mm on the conveyor (1,893
vertices, 3,368 triangles; the built scene carried along the belt, as the size does not
depend on the motion), 21 frames: 5.5 MB, 201 frames (2 s at 10 ms): 9.9 MB, +24.7 kB a
frame. Size grows linearly with frames times vertices; the same scene at 10 mm (about six
times the vertices) would take some 150 kB a frame. A page that would exceed the budget
(``max_mb``, default 20 MB) shows every n-th frame instead (the first and last always) and
says so in its title (the conveyor of four over 1,001 frames: 501 shown, one in 2,
17.3 MB); ``max_frames`` caps the count further. ``view.html#frame=last&field=strain``
opens at that frame and field.

The frame count is exposed for scripts and tests: ``data-frame-count`` (frames shown),
``data-total-frames`` (frames in the results) and ``data-rendered`` (``"yes"`` once the
scene is drawn, ``"no-webgl"`` without WebGL) on ``#flexparcel-viewer``, and the global
``window.flexparcelView``.
"""

from __future__ import annotations

import base64
import html
import json
import math
import warnings
import zipfile
import zlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

__all__ = [
    "VIEW_FILE",
    "DEFAULT_MAX_MB",
    "ViewerError",
    "write_viewer",
    "viewer_writer",
    "load_scene",
    "ViewScene",
]

VIEW_FILE = "view.html"
DEFAULT_MAX_MB = 20.0
"""Default size budget of a page [MB]."""

_PALETTE = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2",
            "#7f7f7f", "#bcbd22", "#17becf")  # fmt: skip
_NO_PRESSURE = "not recorded: no scenario stores contact pressures"
_NO_FORCE = ("not in these results: only the conveyor records contact forces (its deflector "
             "normal forces, contact_forces.npz)")  # fmt: skip


class ViewerError(ValueError):
    """A folder that cannot be shown: missing, or not a results folder."""


@dataclass
class DynamicMesh:
    """A triangle mesh whose vertices move: ``points`` (k, v, 3) [m], ``triangles`` (t, 3);
    ``vertex_fields`` name -> (k, v); ``cell_fields`` name -> (k, t); ``consignment`` (v,)."""

    name: str
    points: np.ndarray
    triangles: np.ndarray
    vertex_fields: dict[str, np.ndarray] = field(default_factory=dict)
    cell_fields: dict[str, np.ndarray] = field(default_factory=dict)
    consignment: np.ndarray | None = None


@dataclass
class ViewScene:
    """What a page shows (:func:`load_scene`)."""

    title: str
    time: np.ndarray
    dynamic: list[DynamicMesh]
    static: list[dict]
    """Plotly Mesh3d trace dicts of the belt, deflectors and plate."""
    consignments: list[str]
    unavailable: dict[str, str]
    """Field -> why the results do not have it."""


# --------------------------------------------------------------------------- reading
_HEX_FACES = np.array([[0, 3, 2, 1], [4, 5, 6, 7], [0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6],
                       [3, 0, 4, 7]])  # fmt: skip
_TET_FACES = np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]])


def _triangulate(ctype: str, conn: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Triangles of surface cells and the cell each came from."""
    m = np.arange(len(conn))
    if ctype == "triangle":
        return conn, m
    if ctype == "quad":
        return np.vstack([conn[:, [0, 1, 2]], conn[:, [0, 2, 3]]]), np.concatenate([m, m])
    raise ValueError(ctype)


def _solid_boundary(ctype: str, conn: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Boundary triangles of a solid block (faces that belong to one cell only) and the
    cell of each."""
    faces = _HEX_FACES if ctype == "hexahedron" else _TET_FACES
    all_f = conn[:, faces]  # (m, f, c)
    owner = np.repeat(np.arange(len(conn)), len(faces))
    all_f = all_f.reshape(-1, faces.shape[1])
    key = np.sort(all_f, axis=1)
    _, inv, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    outer = counts[inv.ravel()] == 1
    f, own = all_f[outer], owner[outer]
    if f.shape[1] == 4:
        return np.vstack([f[:, [0, 1, 2]], f[:, [0, 2, 3]]]), np.concatenate([own, own])
    return f, own


# what numpy, zipfile and zlib raise on a truncated, damaged or foreign .npz
_READ_ERRORS = (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile, zlib.error)


def _read_results(results_dir: Path) -> dict:
    from flexparcel.io.results import load_result

    if not results_dir.exists():
        raise ViewerError(f"{results_dir}: no such folder")
    if not results_dir.is_dir():
        raise ViewerError(f"{results_dir}: not a folder (give the folder a run wrote)")
    path = results_dir / "results.npz"
    if not path.is_file():
        raise ViewerError(
            f"{results_dir}: not a results folder (no results.npz; flexparcel run writes one)"
        )
    try:
        data = load_result(path)
    except _READ_ERRORS as exc:
        raise ViewerError(f"{path}: not a readable results file ({exc})") from None
    for key in ("time", "positions", "velocities", "rotation_vectors"):
        if key not in data:
            raise ViewerError(f"{path}: no {key!r} array; not a flexparcel results file")
    if not any(k.startswith("cells_") for k in data):
        raise ViewerError(f"{path}: no mesh cells (cells_*); the run saved no model")
    return data


def _contact_forces(results_dir: Path, k: int, n: int) -> np.ndarray | None:
    """Contact force per node [N] (k, n, 3) from ``contact_forces.npz``, or None."""
    path = results_dir / "contact_forces.npz"
    if not path.is_file():
        return None
    try:
        with np.load(path, allow_pickle=False) as z:
            frame, node, force = z["frame"], z["node"], z["force_N"]
    except _READ_ERRORS as exc:
        raise ViewerError(f"{path}: not a readable contact force file ({exc})") from None
    out = np.zeros((k, n, 3))
    ok = (frame < k) & (node < n)
    np.add.at(out, (frame[ok], node[ok]), force[ok])
    return out


def _title(meta: dict, results_dir: Path) -> str:
    if meta.get("scenario") == "conveyor":
        n = len(meta.get("consignments", {}))
        return f"Conveyor, {n} consignments ({results_dir.name})"
    test = meta.get("test")
    if test:
        cid = meta.get("consignment", {}).get("spec", {}).get("id", "")
        words = str(test).split("-")  # drop-horizontal -> Horizontal drop test
        name = " ".join([*words[1:], words[0]]).capitalize()
        return f"{name} test, {cid} ({results_dir.name})"
    return f"Results {results_dir.name}"


def load_scene(results_dir: str | Path) -> ViewScene:
    """The meshes and fields of a results folder (``results.npz``, and
    ``contact_forces.npz`` where the run wrote one); :class:`ViewerError` naming the folder
    or file and what is wrong."""
    from flexparcel.io.paraview import (
        cell_strain_stress,
        parts_from_meta,
        ranges_to_ids,
        rigid_content_frames,
    )

    results_dir = Path(results_dir)
    data = _read_results(results_dir)
    meta = data["meta"]
    time = np.asarray(data["time"], float)
    pos = np.asarray(data["positions"], float)
    vel = np.asarray(data["velocities"], float)
    k, n = pos.shape[:2]
    ref = np.asarray(data.get("reference_positions", pos[0]), float)
    cells = [(key[6:], np.asarray(v, np.int64)) for key, v in data.items()
             if key.startswith("cells_")]  # fmt: skip
    parts = parts_from_meta(meta, n)
    cid = np.full(n, -1, np.int64)
    is_content = np.zeros(n, bool)
    names: list[str] = []
    if parts is None:  # a file without parts: every cell is packaging of one consignment
        for _, conn in cells:
            cid[conn.ravel()] = 0
        names = [str(meta.get("consignment", {}).get("spec", {}).get("id", "consignment"))]
    else:
        for i, c in enumerate(parts["consignments"]):
            names.append(str(c["name"]))
            cid[ranges_to_ids(c["packaging"])] = i
            content = ranges_to_ids(c.get("content", []))
            cid[content], is_content[content] = i, True
    force = _contact_forces(results_dir, k, n)
    disp = np.linalg.norm(pos - pos[:1], axis=2) * 1e3  # mm
    speed = np.linalg.norm(vel[..., :3], axis=2)
    fmag = None if force is None else np.linalg.norm(force, axis=2)

    def vertex_fields(nodes: np.ndarray) -> dict[str, np.ndarray]:
        out = {"displacement": disp[:, nodes], "speed": speed[:, nodes]}
        if fmag is not None:
            out["contact_force"] = fmag[:, nodes]
        return out

    def strain(ctype: str, conn: np.ndarray) -> np.ndarray:
        return np.stack([cell_strain_stress(ref, pos[j], ctype, conn)[0] for j in range(k)])

    pack_tri, pack_strain, content_tri, content_strain = [], [], [], []
    for ctype, conn in cells:
        keep = (cid[conn] >= 0).all(axis=1)
        conn = conn[keep]
        if not len(conn):
            continue
        if ctype in ("triangle", "quad"):
            shell = conn[~is_content[conn[:, 0]]]
            tri, owner = _triangulate(ctype, shell)
            pack_tri.append(tri)
            pack_strain.append(strain(ctype, shell)[:, owner] * 100.0)
        elif ctype in ("hexahedron", "tetra"):
            tri, owner = _solid_boundary(ctype, conn)
            content_tri.append(tri)
            content_strain.append(strain(ctype, conn)[:, owner] * 100.0)
    dynamic: list[DynamicMesh] = []
    if pack_tri:
        tri = np.vstack(pack_tri)
        nodes, local = np.unique(tri, return_inverse=True)
        dynamic.append(DynamicMesh(
            "packaging", pos[:, nodes], local.reshape(-1, 3).astype(np.int64),
            vertex_fields(nodes), {"strain": np.nan_to_num(np.hstack(pack_strain))},
            cid[nodes]))  # fmt: skip
    # contents: solid boundaries and rigid rounded boxes in one mesh
    c_pts, c_tri, c_fields, c_strain, c_id = [], [], [], [], []
    base = 0
    if content_tri:
        tri = np.vstack(content_tri)
        nodes, local = np.unique(tri, return_inverse=True)
        c_pts.append(pos[:, nodes])
        c_tri.append(local.reshape(-1, 3))
        c_fields.append(vertex_fields(nodes))
        c_strain.append(np.nan_to_num(np.hstack(content_strain)))
        c_id.append(cid[nodes])
        base = nodes.size
    for i, c in enumerate(parts["consignments"] if parts else []):
        body = c.get("content_body")
        if body is None:
            continue
        p, tri, v = rigid_content_frames(pos, data["rotation_vectors"], vel, int(body),
                                         c["content_half_inner_m"], c["content_edge_radius_m"],
                                         segments=2)  # fmt: skip
        c_pts.append(p)
        c_tri.append(tri + base)
        base += p.shape[1]
        f = {"displacement": np.linalg.norm(p - p[:1], axis=2) * 1e3,
             "speed": np.linalg.norm(v, axis=2)}  # fmt: skip
        if fmag is not None:
            f["contact_force"] = np.zeros(p.shape[:2])
        c_fields.append(f)
        c_strain.append(np.zeros((k, len(tri))))
        c_id.append(np.full(p.shape[1], i))
    if c_pts:
        dynamic.append(DynamicMesh(
            "contents", np.concatenate(c_pts, axis=1), np.vstack(c_tri).astype(np.int64),
            {key: np.concatenate([f[key] for f in c_fields], axis=1) for key in c_fields[0]},
            {"strain": np.concatenate(c_strain, axis=1)}, np.concatenate(c_id)))  # fmt: skip
    if not dynamic:
        raise ViewerError(f"{results_dir / 'results.npz'}: no consignment cells to show")
    unavailable = {"contact_pressure": _NO_PRESSURE}
    if force is None:
        unavailable["contact_force"] = _NO_FORCE
    return ViewScene(_title(meta, results_dir), time, dynamic,
                     _static_traces(parts, cells, pos), names, unavailable)  # fmt: skip


def _static_traces(parts: dict | None, cells, pos: np.ndarray) -> list[dict]:
    """Mesh3d traces of the belt, the deflectors and a drop test's plate."""
    from flexparcel.io.paraview import belt_spans, ranges_to_ids

    out: list[dict] = []
    if not parts:
        return out
    belt = parts.get("belt")
    if belt:
        w = belt["width_m"]
        for a, b, speed in belt_spans(belt):
            out.append({"type": "mesh3d", "name": f"belt ({speed:g} m/s)",
                        "x": [a, b, b, a], "y": [-w / 2, -w / 2, w / 2, w / 2],
                        "z": [0, 0, 0, 0], "i": [0, 0], "j": [1, 2], "k": [2, 3],
                        "color": "#6b6b6b", "opacity": 1.0, "flatshading": True,
                        "hoverinfo": "name", "showlegend": True,
                        "showscale": False})  # fmt: skip
    n = pos.shape[1]
    defl = np.zeros(n, bool)
    for d in parts.get("deflectors", []):
        ids = ranges_to_ids(d)
        defl[ids[ids < n]] = True
    tri = [c for t, c in cells if t == "triangle"]
    if defl.any() and tri:
        tri = np.vstack(tri)
        tri = tri[defl[tri].all(axis=1)]
        if len(tri):
            nodes, local = np.unique(tri, return_inverse=True)
            p = pos[0, nodes]
            local = local.reshape(-1, 3)
            out.append({"type": "mesh3d", "name": "deflectors", "x": p[:, 0], "y": p[:, 1],
                        "z": p[:, 2], "i": local[:, 0], "j": local[:, 1], "k": local[:, 2],
                        "color": "#4a6f8a", "opacity": 1.0, "flatshading": True,
                        "hoverinfo": "name", "showlegend": True,
                        "showscale": False})  # fmt: skip
    if parts.get("plate_z_m") is not None:
        z = float(parts["plate_z_m"])
        lo, hi = pos[..., :2].min(axis=(0, 1)), pos[..., :2].max(axis=(0, 1))
        pad = 0.25 * float(np.max(hi - lo)) + 0.01
        lo, hi = lo - pad, hi + pad
        out.append({"type": "mesh3d", "name": "plate", "x": [lo[0], hi[0], hi[0], lo[0]],
                    "y": [lo[1], lo[1], hi[1], hi[1]], "z": [z] * 4, "i": [0, 0], "j": [1, 2],
                    "k": [2, 3], "color": "#8c8c8c", "opacity": 1.0, "flatshading": True,
                    "hoverinfo": "name", "showlegend": True,
                    "showscale": False})  # fmt: skip
    return out


# --------------------------------------------------------------------------- the page
_FIELDS = {
    # name: (label, colourbar title, mode)
    "displacement": ("displacement from the first frame [mm]", "displacement [mm]", "vertex"),
    "speed": ("speed [m/s]", "speed [m/s]", "vertex"),
    "contact_force": ("contact force [N]", "contact force [N]", "vertex"),
    "contact_pressure": ("contact pressure [Pa]", "contact pressure [Pa]", "vertex"),
    "strain": ("max principal membrane strain [%]", "strain [%]", "cell"),
    "consignment": ("consignment", "consignment", "vertex"),
}


def _b64(a: np.ndarray) -> str:
    return base64.b64encode(np.ascontiguousarray(a).tobytes()).decode("ascii")


def _quantise(values: np.ndarray, lo: float, hi: float) -> np.ndarray:
    span = hi - lo if hi > lo else 1.0
    return np.clip(np.round((values - lo) / span * 255.0), 0, 255).astype(np.uint8)


def _frame_bytes(scene: ViewScene) -> int:
    """Bytes one frame adds to the page (base64 included)."""
    raw = 0
    for m in scene.dynamic:
        v, t = m.points.shape[1], len(m.triangles)
        raw += 6 * v + len(m.vertex_fields) * v + len(m.cell_fields) * t
    return math.ceil(raw * 4 / 3)


def _fixed_bytes(scene: ViewScene) -> int:
    """Bytes of everything but the frames: plotly.js, the triangles, the static parts."""
    from plotly.offline import get_plotlyjs

    tri = sum(m.triangles.size * 4 + m.points.shape[1] * 20 for m in scene.dynamic)
    static = sum(12 * len(t["x"]) * 3 + 12 * len(t["i"]) * 3 for t in scene.static)
    return len(get_plotlyjs()) + 30_000 + tri + static


def choose_frames(count: int, per_frame: int, fixed: int, max_bytes: float,
                  max_frames: int | None = None) -> np.ndarray:  # fmt: skip
    """Indices of the frames to show: all where they fit into ``max_bytes``, else every n-th
    (first and last always; at least those two)."""
    room = max(0.0, max_bytes - fixed)
    fit = max(2, int(room // max(per_frame, 1)))
    if max_frames is not None:
        fit = max(2, min(fit, int(max_frames)))
    if count <= fit:
        return np.arange(count)
    step = math.ceil((count - 1) / (fit - 1))
    idx = np.arange(0, count, step)
    if idx[-1] != count - 1:
        idx = np.append(idx[:-1] if len(idx) >= fit else idx, count - 1)
    return idx


def _eye(scene: ViewScene) -> dict:
    """Camera position: from the front left and above; a long belt seen from further off, so
    that it fits."""
    if any(t.get("name", "").startswith("belt") for t in scene.static):
        return {"x": -0.5, "y": -2.4, "z": 1.3}
    return {"x": -1.4, "y": -1.6, "z": 1.0}


def _categorical(n: int) -> list:
    """A discrete colour scale over ids 0 .. n - 1 (cmin -0.5, cmax n - 0.5)."""
    n = max(n, 1)
    out = []
    for i in range(n):
        c = _PALETTE[i % len(_PALETTE)]
        out += [[i / n, c], [(i + 1) / n, c]]
    return out


def _page(scene: ViewScene, frames: np.ndarray, note: str, total: int) -> str:
    import plotly.graph_objects as go

    dyn = scene.dynamic
    allp = np.concatenate([m.points[frames].reshape(-1, 3) for m in dyn])
    lo = allp.min(axis=0)
    span = np.maximum(allp.max(axis=0) - lo, 1e-9)
    fields: dict[str, dict] = {}
    names = list(_FIELDS)
    for name in names:
        label, cbar, mode = _FIELDS[name]
        if name in scene.unavailable:
            fields[name] = {"label": label, "available": False, "why": scene.unavailable[name]}
            continue
        if name == "consignment":
            n = len(scene.consignments)
            fields[name] = {"label": label, "title": cbar, "mode": "vertex", "static": True,
                            "min": -0.5, "max": n - 0.5, "colorscale": _categorical(n),
                            "tickvals": list(range(n)), "ticktext": scene.consignments,
                            "available": True}  # fmt: skip
            continue
        store = [(m.cell_fields if mode == "cell" else m.vertex_fields).get(name) for m in dyn]
        if all(s is None for s in store):
            continue
        vals = np.concatenate([s[frames].ravel() for s in store if s is not None])
        vmin, vmax = float(np.nanmin(vals)), float(np.nanmax(vals))
        if name in ("displacement", "speed", "contact_force"):
            vmin = 0.0
        if vmax <= vmin:
            vmax = vmin + 1.0
        fields[name] = {"label": label, "title": cbar, "mode": mode, "static": False,
                        "min": vmin, "max": vmax, "colorscale": "Viridis",
                        "available": True}  # fmt: skip
    traces_js = []
    fig = go.Figure()
    for s in scene.static:
        fig.add_trace(go.Mesh3d(**s))
    first = len(scene.static)
    default = "displacement"
    for i, m in enumerate(dyn):
        q = np.round((m.points[frames] - lo) / span * 65535.0).astype("<u2")
        enc = {}
        for name, f in fields.items():
            if not f["available"]:
                continue
            if name == "consignment":
                enc[name] = _b64(np.asarray(m.consignment, np.uint8))
                continue
            src = (m.cell_fields if f["mode"] == "cell" else m.vertex_fields).get(name)
            if src is None:
                n = len(m.triangles) if f["mode"] == "cell" else m.points.shape[1]
                src = np.zeros((m.points.shape[0], n))
            enc[name] = _b64(_quantise(src[frames], f["min"], f["max"]))
        traces_js.append({"index": first + i, "name": m.name, "nv": int(m.points.shape[1]),
                          "nc": int(len(m.triangles)), "positions": _b64(q),
                          "fields": enc})  # fmt: skip
        p0 = m.points[frames[0]]
        f0 = fields[default]
        fig.add_trace(go.Mesh3d(
            x=p0[:, 0], y=p0[:, 1], z=p0[:, 2], i=m.triangles[:, 0], j=m.triangles[:, 1],
            k=m.triangles[:, 2], name=m.name, intensity=m.vertex_fields[default][frames[0]],
            intensitymode="vertex", colorscale=f0["colorscale"], cmin=f0["min"],
            cmax=f0["max"], showscale=(i == 0), colorbar={"title": {"text": f0["title"]}},
            opacity=0.6 if m.name == "packaging" else 1.0, flatshading=False,
            lighting={"ambient": 0.55, "diffuse": 0.7, "specular": 0.1},
            hoverinfo="name", showlegend=True,
        ))  # fmt: skip
    fig.update_layout(
        title={"text": f"{html.escape(scene.title)}<br><sub>{html.escape(note)}</sub>"},
        scene={"aspectmode": "data", "xaxis": {"title": {"text": "x [m]"}},
               "yaxis": {"title": {"text": "y [m]"}}, "zaxis": {"title": {"text": "z [m]"}},
               "camera": {"eye": _eye(scene)}},
        margin={"l": 0, "r": 0, "t": 70, "b": 0}, legend={"x": 0.0, "y": 0.95},
        uirevision="keep",
    )  # fmt: skip
    data = {
        "time": [float(t) for t in scene.time[frames]],
        "frames": [int(f) for f in frames],
        "total_frames": total,
        "lo": [float(v) for v in lo],
        "scale": [float(v) / 65535.0 for v in span],
        "fields": fields,
        "default_field": default,
        "traces": traces_js,
    }
    plot = fig.to_html(include_plotlyjs=True, full_html=False, div_id="flexparcel-plot",
                       post_script="window.flexparcelViewerStart(document.getElementById("
                       "'{plot_id}'));",
                       config={"displaylogo": False, "responsive": True},
                       default_height="calc(100vh - 100px)")  # fmt: skip
    options = "\n".join(
        f'<option value="{k}"{" disabled" if not f["available"] else ""}'
        f"{' selected' if k == default else ''}>"
        f"{html.escape(f['label'])}"
        f"{'' if f['available'] else ' (' + html.escape(f['why']) + ')'}</option>"
        for k, f in fields.items()
    )
    payload = json.dumps(data, separators=(",", ":")).replace("</", "<\\/")
    return _TEMPLATE.format(
        title=html.escape(scene.title), note=html.escape(note), count=len(frames), total=total,
        options=options, data=payload, script=_SCRIPT, plot=plot,
        last=len(frames) - 1,
    )  # fmt: skip


_TEMPLATE = """<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<title>{title}</title>
<style>
body {{ font-family: sans-serif; margin: 0; }}
#flexparcel-controls {{ padding: 6px 10px; display: flex; gap: 12px; align-items: center;
  flex-wrap: wrap; background: #f3f3f3; border-bottom: 1px solid #ccc; font-size: 14px; }}
#flexparcel-slider {{ flex: 1; min-width: 200px; }}
#flexparcel-note {{ padding: 2px 10px; font-size: 12px; color: #555; }}
</style>
</head>
<body>
<div id="flexparcel-viewer" data-frame-count="{count}" data-total-frames="{total}"
  data-rendered="pending">
<div id="flexparcel-controls">
<button id="flexparcel-play" type="button">Play</button>
<input id="flexparcel-slider" type="range" min="0" max="{last}" value="0" step="1">
<span id="flexparcel-time">t = 0 s</span>
<label>colour by <select id="flexparcel-field">
{options}
</select></label>
<label><input id="flexparcel-seethrough" type="checkbox" checked> see-through packaging</label>
</div>
<div id="flexparcel-note">{note}. Drag to turn the camera, scroll to zoom.</div>
<script type="application/json" id="flexparcel-data">{data}</script>
<script>{script}</script>
{plot}
</div>
</body>
</html>
"""

_SCRIPT = r"""
(function () {
  "use strict";
  var data = JSON.parse(document.getElementById("flexparcel-data").textContent);
  window.flexparcelView = {frameCount: data.frames.length, totalFrames: data.total_frames,
                           frame: 0, field: data.default_field, rendered: false};
  function bytes(s) {
    var bin = atob(s), out = new Uint8Array(bin.length);
    for (var i = 0; i < bin.length; i++) out[i] = bin.charCodeAt(i);
    return out;
  }
  window.flexparcelViewerStart = function (gd) {
    var root = document.getElementById("flexparcel-viewer");
    var gl = null;
    try {
      var c = document.createElement("canvas");
      gl = c.getContext("webgl") || c.getContext("experimental-webgl");
    } catch (e) { gl = null; }
    var traces = data.traces.map(function (t) {
      var f = {};
      Object.keys(t.fields).forEach(function (k) { f[k] = bytes(t.fields[k]); });
      return {index: t.index, nv: t.nv, nc: t.nc, pos: new Uint16Array(bytes(t.positions).buffer),
              fields: f};
    });
    var slider = document.getElementById("flexparcel-slider");
    var label = document.getElementById("flexparcel-time");
    var play = document.getElementById("flexparcel-play");
    var select = document.getElementById("flexparcel-field");
    var see = document.getElementById("flexparcel-seethrough");
    var state = {frame: 0, field: data.default_field, playing: false, busy: false};
    function coords(t, k) {
      var n = t.nv, base = k * n * 3, lo = data.lo, s = data.scale;
      var x = new Float32Array(n), y = new Float32Array(n), z = new Float32Array(n);
      for (var i = 0; i < n; i++) {
        x[i] = lo[0] + t.pos[base + 3 * i] * s[0];
        y[i] = lo[1] + t.pos[base + 3 * i + 1] * s[1];
        z[i] = lo[2] + t.pos[base + 3 * i + 2] * s[2];
      }
      return [x, y, z];
    }
    function values(t, name, k) {
      var f = data.fields[name], q = t.fields[name];
      var n = f.mode === "cell" ? t.nc : t.nv, off = f.static ? 0 : k * n;
      var out = new Float32Array(n), step = (f.max - f.min) / 255.0;
      if (f.static) { for (var i = 0; i < n; i++) out[i] = q[i]; return out; }
      for (var j = 0; j < n; j++) out[j] = f.min + q[off + j] * step;
      return out;
    }
    function show(k) {
      var f = data.fields[state.field];
      var upd = {x: [], y: [], z: [], intensity: [], intensitymode: [], cmin: [], cmax: [],
                 colorscale: [], "colorbar.title.text": [], "colorbar.tickvals": [],
                 "colorbar.ticktext": []};
      var idx = [];
      traces.forEach(function (t) {
        var c = coords(t, k);
        upd.x.push(c[0]); upd.y.push(c[1]); upd.z.push(c[2]);
        upd.intensity.push(values(t, state.field, k));
        upd.intensitymode.push(f.mode);
        upd.cmin.push(f.min); upd.cmax.push(f.max);
        upd.colorscale.push(f.colorscale);
        upd["colorbar.title.text"].push(f.title);
        upd["colorbar.tickvals"].push(f.tickvals || null);
        upd["colorbar.ticktext"].push(f.ticktext || null);
        idx.push(t.index);
      });
      state.frame = k;
      return Plotly.restyle(gd, upd, idx).then(function () {
        slider.value = k;
        label.textContent = "t = " + data.time[k].toFixed(4) + " s (frame " + (k + 1) +
          " of " + data.frames.length + ")";
        root.setAttribute("data-frame", String(k));
        root.setAttribute("data-field", state.field);
        window.flexparcelView.frame = k;
        window.flexparcelView.field = state.field;
      });
    }
    function tick() {
      if (!state.playing) return;
      var t0 = Date.now();
      var next = (state.frame + 1) % data.frames.length;
      show(next).then(function () {
        setTimeout(tick, Math.max(0, 66 - (Date.now() - t0)));
      });
    }
    play.addEventListener("click", function () {
      state.playing = !state.playing;
      play.textContent = state.playing ? "Pause" : "Play";
      if (state.playing) tick();
    });
    slider.addEventListener("input", function () {
      state.playing = false; play.textContent = "Play";
      show(parseInt(slider.value, 10));
    });
    select.addEventListener("change", function () {
      state.field = select.value;
      show(state.frame);
    });
    see.addEventListener("change", function () {
      traces.forEach(function (t) {
        if (data.traces.find(function (d) { return d.index === t.index; }).name === "packaging")
          Plotly.restyle(gd, {opacity: see.checked ? 0.6 : 1.0}, [t.index]);
      });
    });
    // view.html#frame=last&field=strain opens at that frame and field
    var start = 0;
    (window.location.hash || "").replace(/^#/, "").split("&").forEach(function (kv) {
      var p = kv.split("="), v = decodeURIComponent(p[1] || "");
      if (p[0] === "frame") {
        var n = data.frames.length;
        start = v === "last" ? n - 1 : Math.max(0, Math.min(n - 1, parseInt(v, 10) || 0));
      } else if (p[0] === "field" && data.fields[v] && data.fields[v].available) {
        state.field = v;
        select.value = v;
      }
    });
    show(start).then(function () {
      var drawn = gl && gd.querySelector("canvas") !== null;
      root.setAttribute("data-rendered", drawn ? "yes" : "no-webgl");
      window.flexparcelView.rendered = !!drawn;
    }, function (err) {
      root.setAttribute("data-rendered", "error: " + err);
    });
  };
})();
"""


# --------------------------------------------------------------------------- writers
def write_viewer(
    results_dir: str | Path,
    out: str | Path | None = None,
    *,
    max_mb: float = DEFAULT_MAX_MB,
    max_frames: int | None = None,
) -> Path:
    """Write the viewer page of ``results_dir`` to ``out`` (default
    ``RESULTS_DIR/view.html``) atomically; returns its path. Frames are subsampled to keep
    the page within ``max_mb`` [MB] (and ``max_frames``); the page says so."""
    from flexparcel.io.atomic import write_atomic

    if not (isinstance(max_mb, int | float) and math.isfinite(max_mb) and max_mb > 0):
        raise ValueError(f"max_mb must be > 0 MB, got {max_mb!r}")
    if max_frames is not None and int(max_frames) < 2:
        raise ValueError(f"max_frames must be >= 2, got {max_frames!r}")
    results_dir = Path(results_dir)
    scene = load_scene(results_dir)
    total = len(scene.time)
    frames = choose_frames(total, _frame_bytes(scene), _fixed_bytes(scene), max_mb * 1e6,
                           max_frames)  # fmt: skip
    t = scene.time
    span = f"t = {t[0]:.4g} to {t[-1]:.4g} s"
    if len(frames) == total:
        note = f"all {total} saved frames, {span}"
    else:
        step = int(frames[1] - frames[0]) if len(frames) > 1 else 1
        why = (f"to stay within {max_mb:g} MB" if max_frames is None or len(frames) < max_frames
               else f"at most {max_frames} frames asked")  # fmt: skip
        note = (f"subsampled: {len(frames)} of {total} saved frames (one in {step}, and the "
                f"last), {why}; {span}")  # fmt: skip
    page = _page(scene, frames, note, total)
    return write_atomic(Path(out) if out is not None else results_dir / VIEW_FILE, page)


def viewer_writer(result: Any, out: Path) -> dict[str, Path]:
    """A picture writer (:data:`~flexparcel.scenarios.base.PictureWriter`) that writes
    ``out/view.html`` from the results the scenario's ``write`` has just saved there;
    nothing for a scenario that saved no ``results.npz``, and a warning instead of the page
    where plotly is not installed or the results cannot be shown (no mesh cells): a run's
    files never fail on the viewer."""
    if not (Path(out) / "results.npz").is_file():
        return {}
    try:
        import plotly  # noqa: F401
    except ImportError:  # an install from before the viewer: the run's files stay complete
        warnings.warn(
            f"{Path(out) / VIEW_FILE} not written: the viewer needs plotly "
            "(pip install 'flexparcel[io]')",
            stacklevel=2,
        )
        return {}
    try:
        return {"viewer": write_viewer(out)}
    except ViewerError as exc:  # a third-party scenario's results without a mesh, say
        warnings.warn(f"{Path(out) / VIEW_FILE} not written: {exc}", stacklevel=2)
        return {}
