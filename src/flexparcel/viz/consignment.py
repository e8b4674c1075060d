"""Pictures of consignments: side and top views of a state, frame sequences like the paper's
figures, and the swing and drop response curves (matplotlib, Agg backend, imported lazily).

Views are orthographic projections of the mesh: every shell cell (and every face of a solid
cell) is drawn as a translucent polygon, so a view shows the packaging's outline and how its
layers bend; rigid contents are drawn as the outline of their box. Coordinates are plotted in
mm; inputs are SI (m).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from flexparcel.scenarios.drop import DropCurve

__all__ = [
    "Box",
    "plot_consignment_views",
    "plot_frames",
    "plot_swing_curve",
    "plot_drop_curve",
]

PACKAGING_COLOUR = "#c8a165"
CONTENT_COLOUR = "#5a6e8c"

# Faces of the VTK solid cells, as local node indices (enough to draw them; orientation unused)
_SOLID_FACES: dict[str, list[tuple[int, ...]]] = {
    "hexahedron": [(0, 1, 2, 3), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6),
                   (3, 0, 4, 7)],
    "wedge": [(0, 1, 2), (3, 4, 5), (0, 1, 4, 3), (1, 2, 5, 4), (2, 0, 3, 5)],
    "pyramid": [(0, 1, 2, 3), (0, 1, 4), (1, 2, 4), (2, 3, 4), (3, 0, 4)],
    "tetra": [(0, 1, 2), (0, 1, 3), (1, 2, 3), (2, 0, 3)],
}  # fmt: skip


@dataclass(frozen=True)
class Box:
    """A rigid box to draw: centre [m] (3,), rotation matrix body -> world (3, 3), edge
    lengths [m] (3,) along the body axes."""

    centre: np.ndarray
    rotation: np.ndarray
    size: tuple[float, float, float]

    def corners(self) -> np.ndarray:
        """The 8 corners [m], shape (8, 3)."""
        s = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)], float)
        local = 0.5 * s * np.asarray(self.size, float)
        return np.asarray(self.centre, float) + local @ np.asarray(self.rotation, float).T


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _polygons(positions: np.ndarray, cells, axes: tuple[int, int]) -> tuple[list, list]:
    """Projected polygons [mm] of shell cells and of solid-cell faces: (shells, solids)."""
    xy = 1e3 * positions[:, list(axes)]
    shells, solids = [], []
    for ctype, conn in cells:
        conn = np.asarray(conn)
        if ctype in ("quad", "triangle"):
            shells.extend(xy[conn])
        elif ctype in _SOLID_FACES:
            for face in _SOLID_FACES[ctype]:
                solids.extend(xy[conn[:, list(face)]])
    return shells, solids


def _draw(ax, positions: np.ndarray, cells, boxes: Sequence[Box], axes: tuple[int, int]) -> None:
    from matplotlib.collections import PolyCollection
    from matplotlib.patches import Polygon
    from scipy.spatial import ConvexHull

    shells, solids = _polygons(positions, cells, axes)
    if solids:
        ax.add_collection(PolyCollection(solids, facecolors=CONTENT_COLOUR, alpha=0.15,
                                         edgecolors=CONTENT_COLOUR, linewidths=0.2))  # fmt: skip
    for box in boxes:
        pts = 1e3 * box.corners()[:, list(axes)]
        hull = pts[ConvexHull(pts).vertices]
        ax.add_patch(Polygon(hull, closed=True, facecolor=CONTENT_COLOUR, alpha=0.5,
                             edgecolor="k", linewidth=0.8))  # fmt: skip
    if shells:
        ax.add_collection(PolyCollection(shells, facecolors=PACKAGING_COLOUR, alpha=0.25,
                                         edgecolors="#7a5a2a", linewidths=0.3))  # fmt: skip
    ax.set_aspect("equal")
    ax.autoscale_view()


def save_figure(fig, path: str | Path, dpi: float | None = None) -> Path:
    """Write ``fig`` to ``path`` atomically (a temporary file in the same folder, then
    ``os.replace``: a reader never sees half a picture) in the format of its suffix (PNG
    without one) and close it; returns ``path``."""
    from flexparcel.io.atomic import write_atomic

    path = Path(path)
    fmt = path.suffix[1:].lower() or "png"
    try:
        write_atomic(path, lambda fh: fig.savefig(fh, format=fmt, dpi=dpi))
    finally:
        import matplotlib.pyplot as plt

        plt.close(fig)
    return path


_save = save_figure


def _finish(fig, path: str | Path, title: str = "", dpi: float | None = None) -> Path:
    """Title (if any), tight layout, save to ``path`` and close: the end of every picture."""
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return _save(fig, path, dpi)


def plot_consignment_views(
    path: str | Path,
    positions: np.ndarray,
    cells: Sequence[tuple[str, np.ndarray]],
    *,
    boxes: Sequence[Box] = (),
    title: str = "",
) -> Path:
    """Side view (x-z) and top view (x-y) of one state into a PNG at ``path``.

    ``positions`` [m] (n, 3); ``cells``: (VTK type, connectivity) pairs as in ``Model.cells``.
    """
    plt = _pyplot()
    span = np.ptp(positions, axis=0) + 1e-9
    # panel heights follow the (equal-aspect) views, so that a flat envelope gets no empty band
    ratios = [max(span[2] / span[0], 0.12), max(span[1] / span[0], 0.12)]
    fig, (side, top) = plt.subplots(2, 1, figsize=(7.0, 6.0 * sum(ratios) + 2.0), dpi=120,
                                    gridspec_kw={"height_ratios": ratios})  # fmt: skip
    _draw(side, positions, cells, boxes, (0, 2))
    side.set_xlabel("x [mm]")
    side.set_ylabel("z [mm]")
    side.set_title("side view")
    _draw(top, positions, cells, boxes, (0, 1))
    top.set_xlabel("x [mm]")
    top.set_ylabel("y [mm]")
    top.set_title("top view")
    for ax in (side, top):
        ax.grid(True, alpha=0.3)
    return _finish(fig, path, title)


def plot_frames(
    path: str | Path,
    frames: Sequence[tuple[float, np.ndarray, Sequence[Box]]],
    cells: Sequence[tuple[str, np.ndarray]],
    *,
    title: str = "",
    plate_z: float | None = None,
    clamp_x: float | None = None,
    labels: Sequence[str] | None = None,
    shared_axes: bool = True,
) -> Path:
    """Side views (x-z) of a few states next to each other (like the paper's figures of the
    swing and drop tests), all at the same scale.

    ``frames``: (time [s], positions [m] (n, 3), rigid boxes); ``plate_z`` [m]: draw the
    ground plate; ``clamp_x`` [m]: mark the clamp edge; ``labels``: a caption per frame added
    to its time. ``shared_axes``: one window for all frames (a swing about a fixed clamp);
    otherwise each frame gets a window of the same size centred on the consignment (a drop,
    whose 200 mm fall would leave the consignment a speck in a shared window).
    """
    plt = _pyplot()
    k = len(frames)
    if k == 0:
        raise ValueError("plot_frames: no frames")
    lows = np.array([1e3 * p[:, [0, 2]].min(axis=0) for _, p, _ in frames])
    highs = np.array([1e3 * p[:, [0, 2]].max(axis=0) for _, p, _ in frames])
    if shared_axes:
        lo, hi = lows.min(axis=0), highs.max(axis=0)
        if plate_z is not None:
            lo[1] = min(lo[1], 1e3 * plate_z)
        windows = [(lo, hi)] * k
    else:
        span = (highs - lows).max(axis=0)
        span = np.maximum(span, 0.25 * span.max())  # not a sliver when seen edge-on
        mid = 0.5 * (lows + highs)
        windows = [(m - span / 2, m + span / 2) for m in mid]
    span = windows[0][1] - windows[0][0]
    pad = 0.05 * max(span) + 2.0
    # panels as tall as the (equal-aspect) window needs, plus room for titles and labels
    aspect = (span[1] + 2 * pad) / (span[0] + 2 * pad)
    height = float(np.clip(3.0 * aspect, 0.8, 6.0)) + 1.4
    fig, axs = plt.subplots(1, k, figsize=(3.0 * k, height), dpi=120, squeeze=False,
                            sharex=shared_axes, sharey=shared_axes)  # fmt: skip
    for i, (t, pos, boxes) in enumerate(frames):
        ax = axs[0, i]
        _draw(ax, pos, cells, boxes, (0, 2))
        if plate_z is not None:
            ax.axhline(1e3 * plate_z, color="0.3", linewidth=2.0)
        if clamp_x is not None:
            ax.axvline(1e3 * clamp_x, color="tab:red", linewidth=0.8, linestyle="--")
        caption = f"t = {t:.3f} s"
        if labels is not None and labels[i]:
            caption += f", {labels[i]}"
        ax.set_title(caption, fontsize=9)
        lo, hi = windows[i]
        ax.set_xlim(lo[0] - pad, hi[0] + pad)
        ax.set_ylim(lo[1] - pad, hi[1] + pad)
        ax.set_xlabel("x [mm]")
        ax.grid(True, alpha=0.3)
    axs[0, 0].set_ylabel("z [mm]")
    return _finish(fig, path, title)


_REFERENCE_STYLE = {"table7": ("tab:purple", "--"), "real": ("k", ":")}
"""Colour and line style of the reference lines: paper Table 7 (RecurDyn), real-world test."""


def _reference_lines(ax, references: Sequence[tuple[str, float, str]]) -> None:
    """Horizontal reference lines ``(label, height [mm], kind)``, kind ``"table7"`` or
    ``"real"``; one legend entry per label."""
    shown = set()
    for label, y, kind in references:
        colour, style = _REFERENCE_STYLE[kind]
        ax.axhline(y, color=colour, linewidth=0.9, linestyle=style,
                   label=None if label in shown else label)  # fmt: skip
        shown.add(label)


def plot_swing_curve(
    path: str | Path,
    time: np.ndarray,
    x_rel: np.ndarray,
    *,
    first: tuple[int, float] | None,
    second: tuple[int, float] | None,
    title: str = "Swing test",
    references: Sequence[tuple[str, float, str]] = (),
) -> Path:
    """The free end's horizontal position relative to the clamp edge [m] (k,) over ``time``
    [s] (k,), with the first and second swing marked: ``(frame index, response [m])`` each,
    or None where there is none. ``references``: ``(label, swing [m], kind)`` drawn where
    that swing would peak (the first past the clamp, -swing; the second back, +swing), kind
    ``"table7"`` or ``"real"``."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(7.0, 4.0), dpi=120)
    ax.plot(time, 1e3 * np.asarray(x_rel), color="tab:blue", label="free end x - clamp edge x")
    ax.axhline(0.0, color="0.4", linewidth=0.8, linestyle="--", label="below the clamp")
    _reference_lines(ax, [(label, 1e3 * y, kind) for label, y, kind in references])
    for mark, name, colour in ((first, "first swing", "tab:red"),
                               (second, "second swing", "tab:green")):  # fmt: skip
        if mark is None:
            continue
        k, value = mark
        y = 1e3 * x_rel[k]
        ax.plot([time[k]], [y], "o", color=colour)
        ax.annotate(f"{name} {1e3 * value:.1f} mm", (time[k], y), textcoords="offset points",
                    xytext=(8, -14 if y < 0 else 6), color=colour)  # fmt: skip
    ax.set_xlabel("time [s]")
    ax.set_ylabel("horizontal position [mm]")
    ax.set_title(title)
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    fig.tight_layout()
    return _save(fig, path)


def plot_drop_curve(
    path: str | Path,
    time: np.ndarray,
    curve: DropCurve,
    *,
    rebound: float | None,
    com_rise: float | None = None,
    title: str = "Drop test",
    references: Sequence[tuple[str, float, str]] = (),
) -> Path:
    """The drop's two responses over ``time`` [s] (k,), each with the line it is measured
    from. Top: the gap between the plate and the consignment's lowest point (``curve.gap``),
    measured from the plate (gap 0), with the rebound ``rebound`` [m] (the largest clearance
    after the first touch; None: not reached, not marked) at ``curve.gap_peak``. Bottom: the
    centre of mass's height, measured from its height at the first contact, with its rise
    ``com_rise`` [m] at ``curve.centre_peak``. ``references``: ``(label, rebound [m], kind)``
    drawn at that clearance above the plate, kind ``"table7"`` or ``"real"``."""
    plt = _pyplot()
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(7.0, 6.0), dpi=120, sharex=True)
    gap_mm = 1e3 * np.asarray(curve.gap)
    top.plot(time, gap_mm, color="tab:blue", label="lowest point above the plate")
    top.axhline(0.0, color="0.3", linewidth=1.0, label="plate (rebound measured from here)")
    _reference_lines(top, [(label, 1e3 * r, kind) for label, r, kind in references])
    if rebound is not None and curve.gap_peak is not None:
        k = curve.gap_peak
        top.axhline(1e3 * rebound, color="tab:red", linewidth=0.8, label="rebound peak")
        top.plot([time[k]], [gap_mm[k]], "o", color="tab:red")
        top.annotate(f"rebound {1e3 * rebound:.1f} mm", (time[k], gap_mm[k]),
                     textcoords="offset points", xytext=(8, 6), color="tab:red")  # fmt: skip
    # the fall from 200 mm would squash the bounce: show the last 60 mm above the plate
    top.set_ylim(min(-1.0, float(gap_mm.min()) - 1.0), max(60.0, 1e3 * (rebound or 0.0) + 5.0))
    top.set_ylabel("clearance [mm]")
    top.set_title(title)
    top.grid(True, alpha=0.3)
    top.legend(loc="best", fontsize=8)
    zc = 1e3 * np.asarray(curve.z_centre)
    bottom.plot(time, zc, color="tab:purple", label="centre of mass height")
    if curve.touch is not None:
        t_touch, z_touch = curve.touch
        bottom.axhline(1e3 * z_touch, color="tab:orange", linewidth=0.9, linestyle="-.",
                       label="height at first contact (rise measured from here)")  # fmt: skip
        bottom.plot([t_touch], [1e3 * z_touch], "s", color="0.2")
        if com_rise is not None and curve.centre_peak is not None:
            k = curve.centre_peak
            bottom.plot([time[k]], [zc[k]], "o", color="tab:green")
            bottom.annotate(f"centre rise {1e3 * com_rise:.1f} mm", (time[k], zc[k]),
                            textcoords="offset points", xytext=(8, 6),
                            color="tab:green")  # fmt: skip
    bottom.set_xlabel("time [s]")
    bottom.set_ylabel("height [mm]")
    bottom.grid(True, alpha=0.3)
    bottom.legend(loc="best", fontsize=8)
    fig.tight_layout()
    return _save(fig, path)
