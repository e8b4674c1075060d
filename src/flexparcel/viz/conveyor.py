"""Pictures of a conveyor run: top-view snapshots (like the paper's Fig. 35), the consignments'
trajectories and an animation (top view and perspective) as a GIF (matplotlib with the Pillow
writer, imported lazily). Inputs are SI (m, s); plots are in mm.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from flexparcel.scenarios.conveyor import ConveyorScene
from flexparcel.viz.consignment import (
    CONTENT_COLOUR,
    PACKAGING_COLOUR,
    Box,
    _draw,
    _finish,
    _pyplot,
)

__all__ = ["plot_conveyor_snapshots", "plot_trajectories", "plot_conveyor_motion",
           "centroid_speed", "animate_conveyor"]  # fmt: skip

BELT_COLOUR = "#d9d9d9"
DEFLECTOR_COLOUR = "#404040"


def _belt(ax, scene: ConveyorScene) -> None:
    """Belt outline and deflector faces in a top view [mm]."""
    from matplotlib.patches import Rectangle

    w = scene.belt_width * 1e3
    for x0, x1, _ in scene.belt_spans():
        ax.add_patch(Rectangle((x0 * 1e3, -w / 2), (x1 - x0) * 1e3, w, facecolor=BELT_COLOUR,
                               edgecolor="k", linewidth=0.6, zorder=0))  # fmt: skip
    for g in scene.deflectors():
        p = 1e3 * np.array([g.outer_end, g.tip])
        ax.plot(p[:, 0], p[:, 1], color=DEFLECTOR_COLOUR, linewidth=2.5, zorder=3)


def _top_limits(ax, scene: ConveyorScene, positions: np.ndarray | None = None) -> None:
    hi = scene.exit_x
    if positions is not None:
        hi = max(hi, float(positions[..., 0].max()) + 0.05)
    lo = 0.0 if positions is None else min(0.0, float(positions[..., 0].min()) - 0.05)
    ax.set_xlim(lo * 1e3, hi * 1e3)
    w = 0.5e3 * scene.belt_width + 30.0
    ax.set_ylim(-w, w)
    ax.set_aspect("equal")


def plot_conveyor_snapshots(
    path: str | Path,
    frames: Sequence[tuple[float, np.ndarray, Sequence[Box]]],
    cells,
    scene: ConveyorScene,
    *,
    title: str = "",
) -> Path:
    """Top views, one panel per ``(time [s], positions [m] (n, 3), boxes)`` in ``frames``,
    stacked like the paper's Fig. 35; ``cells`` ``[(type, connectivity)]`` of the
    consignments (leave out the deflector meshes)."""
    plt = _pyplot()
    k = len(frames)
    aspect = scene.belt_width / scene.exit_x
    fig, axes = plt.subplots(k, 1, figsize=(11, max(2.2, 11 * aspect + 0.6) * k), squeeze=False)
    everything = np.stack([f[1] for f in frames])
    for ax, (t, pos, boxes) in zip(axes[:, 0], frames, strict=True):
        _belt(ax, scene)
        _draw(ax, pos, cells, boxes, (0, 1))
        _top_limits(ax, scene, everything)
        ax.set_title(f"t = {t:.2f} s", fontsize=9)
        ax.set_ylabel("y [mm]")
    axes[-1, 0].set_xlabel("x (belt direction) [mm]")
    return _finish(fig, path, title, dpi=100)


def plot_trajectories(
    path: str | Path,
    responses: Mapping,
    scene: ConveyorScene,
    *,
    title: str = "",
) -> Path:
    """Centroid paths on the belt (top view) and x(t) of each consignment; ``responses``:
    name -> :class:`~flexparcel.scenarios.conveyor_responses.ConsignmentResponse`. Exit
    times are marked."""
    plt = _pyplot()
    fig, (top, xt) = plt.subplots(2, 1, figsize=(10, 7.5),
                                  gridspec_kw={"height_ratios": [1, 1.2]})  # fmt: skip
    _belt(top, scene)
    allc = np.concatenate([r.centroid for r in responses.values()])
    for name, r in responses.items():
        c = 1e3 * r.centroid
        (line,) = top.plot(c[:, 0], c[:, 1], linewidth=1.5, label=name)
        top.plot(c[0, 0], c[0, 1], "o", color=line.get_color(), markersize=4)
        xt.plot(r.time, c[:, 0], color=line.get_color(), label=name)
        if r.exit_time is not None:
            xt.plot(r.exit_time, 1e3 * r.exit_position[0], "x", color=line.get_color())
    _top_limits(top, scene, allc[None])
    top.set_xlabel("x [mm]")
    top.set_ylabel("y [mm]")
    top.set_title("centroid paths (o: start)", fontsize=9)
    top.legend(fontsize=8, loc="upper right")
    xt.axhline(scene.exit_x * 1e3, color="k", linestyle=":", linewidth=0.8)
    for x in scene.deflector_x:
        xt.axhline(x * 1e3, color=DEFLECTOR_COLOUR, linestyle="--", linewidth=0.6)
    xt.set_xlabel("t [s]")
    xt.set_ylabel("centroid x [mm]")
    xt.set_title("progress along the belt (dashed: deflector roots, dotted: belt end, "
                 "x: exit)", fontsize=9)  # fmt: skip
    return _finish(fig, path, title, dpi=100)


def centroid_speed(t: np.ndarray, centroid: np.ndarray) -> np.ndarray:
    """Speed of a centroid [m/s] (k,) from its positions [m] (k, 3) at times ``t`` [s] (k,),
    by central differences (one-sided at the ends)."""
    t = np.asarray(t, float)
    if t.size < 2:
        return np.zeros(t.size)
    return np.linalg.norm(np.gradient(np.asarray(centroid, float), t, axis=0), axis=1)


def plot_conveyor_motion(
    path: str | Path, consignments: Mapping[str, Mapping], belt_speed: float, *, title: str = ""
) -> Path:
    """Speed, yaw and deflector force of each consignment against time (three panels).

    ``consignments``: name -> its ``responses.json`` entry
    (:meth:`~flexparcel.scenarios.conveyor_responses.ConsignmentResponse.to_dict`:
    ``trajectory`` with ``t_s``, ``x_m``, ``y_m``, ``z_m``; ``yaw_deg`` and
    ``contact_force_N``, each a list or null); ``belt_speed`` [m/s] is drawn as a line. A
    consignment without yaw or force is left out of that panel, and the panel says so."""
    plt = _pyplot()
    fig, (vx, yx, fx) = plt.subplots(3, 1, figsize=(9, 8.5), sharex=True)
    missing: dict[str, list[str]] = {"yaw": [], "force": []}
    for name, c in consignments.items():
        tr = c["trajectory"]
        t = np.asarray(tr["t_s"], float)
        xyz = np.column_stack([tr["x_m"], tr["y_m"], tr["z_m"]])
        (line,) = vx.plot(t, centroid_speed(t, xyz), label=name)
        colour = line.get_color()
        if c.get("yaw_deg") is None:
            missing["yaw"].append(name)
        else:
            yx.plot(t, c["yaw_deg"], color=colour, label=name)
        if c.get("contact_force_N") is None:
            missing["force"].append(name)
        else:
            # each value is the mean over the interval that ends at its frame
            fx.step(t, c["contact_force_N"], where="pre", color=colour, label=name)
    vx.axhline(belt_speed, color="k", linestyle=":", linewidth=0.8, label="belt")
    vx.set_ylabel("centroid speed [m/s]")
    yx.set_ylabel("yaw [deg]")
    fx.set_ylabel("deflector force [N]\n(mean over each frame interval)")
    fx.set_xlabel("t [s]")
    notes = {"yaw": "no yaw (no clear long axis)", "force": "no force recorded"}
    for ax, key in ((yx, "yaw"), (fx, "force")):
        if missing[key]:
            ax.set_title(f"{notes[key]}: {', '.join(missing[key])}", fontsize=8)
    for ax in (vx, yx, fx):
        ax.grid(True, alpha=0.3)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=8, loc="best")
    return _finish(fig, path, title, dpi=100)


def _shell_polys_3d(positions: np.ndarray, cells) -> list:
    polys = []
    for ctype, conn in cells:
        if ctype in ("quad", "triangle"):
            polys.extend(positions[np.asarray(conn)] * 1e3)
    return polys


def _box_faces(box: Box) -> list:
    c = box.corners() * 1e3  # index bits: (x, y, z) -> 4x + 2y + z
    faces = [(0, 1, 3, 2), (4, 5, 7, 6), (0, 1, 5, 4), (2, 3, 7, 6), (0, 2, 6, 4), (1, 3, 7, 5)]
    return [c[list(f)] for f in faces]


def animate_conveyor(
    path: str | Path,
    time: np.ndarray,
    positions: np.ndarray,
    cells,
    scene: ConveyorScene,
    boxes: Sequence[Sequence[Box]] | None = None,
    *,
    max_frames: int = 60,
    fps: int = 10,
    title: str = "",
) -> Path:
    """GIF of the run: top view (left) and a perspective view (right). ``time`` [s] (k,),
    ``positions`` [m] (k, n, 3), ``cells`` of the consignments, ``boxes`` per frame (rigid
    contents) or None; at most ``max_frames`` evenly spaced frames at ``fps``."""
    plt = _pyplot()
    from matplotlib.animation import FuncAnimation, PillowWriter
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    k = len(time)
    idx = np.unique(np.linspace(0, k - 1, min(k, max(2, int(max_frames)))).round().astype(int))
    fig = plt.figure(figsize=(12, 4.8))
    ax2 = fig.add_subplot(1, 2, 1)
    ax3 = fig.add_subplot(1, 2, 2, projection="3d")
    everything = positions[idx]
    w = scene.belt_width * 1e3
    lx = scene.exit_x * 1e3
    hmax = max(scene.deflector_height * 1e3, 50.0)

    def static3d() -> None:
        belt = [
            [(x0, -w / 2, 0), (x1, -w / 2, 0), (x1, w / 2, 0), (x0, w / 2, 0)]
            for x0, x1 in (1e3 * np.array(span[:2]) for span in scene.belt_spans())
        ]
        ax3.add_collection3d(Poly3DCollection(belt, facecolor=BELT_COLOUR, alpha=0.5))
        faces = []
        deflectors = scene.deflectors()
        for g in deflectors:
            a, b = g.outer_end * 1e3, g.tip * 1e3
            up = np.array([0.0, 0.0, g.height * 1e3])
            faces.append([a, b, b + up, a + up])
        ax3.add_collection3d(Poly3DCollection(faces, facecolor=DEFLECTOR_COLOUR, alpha=0.6))
        ax3.set_xlim(0, lx)
        reach = max([w / 2] + [abs(g.outer_end[1]) * 1e3 for g in deflectors])
        ax3.set_ylim(-reach, reach)
        ax3.set_zlim(0, hmax)
        ax3.set_box_aspect((lx, 2 * reach, 3 * hmax))
        ax3.view_init(elev=30, azim=-60)
        ax3.set_xlabel("x [mm]")
        ax3.set_ylabel("y [mm]")

    def draw(j: int):
        f = int(idx[j])
        ax2.clear()
        _belt(ax2, scene)
        fb = [] if boxes is None else list(boxes[f])
        _draw(ax2, positions[f], cells, fb, (0, 1))
        _top_limits(ax2, scene, everything)
        ax2.set_title(f"top view, t = {time[f]:.3f} s", fontsize=9)
        ax2.set_xlabel("x [mm]")
        ax2.set_ylabel("y [mm]")
        ax3.clear()
        static3d()
        ax3.add_collection3d(Poly3DCollection(
            _shell_polys_3d(positions[f], cells), facecolor=PACKAGING_COLOUR, alpha=0.6,
            edgecolor="#7a5a2a", linewidths=0.2,
        ))  # fmt: skip
        for box in fb:
            ax3.add_collection3d(Poly3DCollection(_box_faces(box), facecolor=CONTENT_COLOUR,
                                                  alpha=0.8))  # fmt: skip
        ax3.set_title("perspective", fontsize=9)
        return []

    if title:
        fig.suptitle(title)
    anim = FuncAnimation(fig, draw, frames=len(idx), blit=False)
    path = Path(path)
    from flexparcel.io.atomic import atomic_path

    try:
        # a temporary .gif in the same folder, moved into place when complete
        with atomic_path(path) as tmp:
            anim.save(str(tmp), writer=PillowWriter(fps=int(fps)))
    finally:
        plt.close(fig)
    return path
