"""Snapshots of assembled consignments: the settled state every test starts from.

A snapshot holds the :class:`ConsignmentBuild` (so the same mesh can be rebuilt with the same
node numbering), the reference positions (checked on load: a snapshot only fits the mesh it was
made on) and the settled node positions and rotation matrices. The prestress is not stored: it
follows exactly from the settled state and the stress-free reference mesh. Stored as ``.npz``
(``allow_pickle=False``), written atomically; loading reproduces the arrays bit for bit.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from flexparcel import __version__
from flexparcel.consignments.build import ConsignmentBuild
from flexparcel.io.atomic import write_atomic
from flexparcel.io.results import FileFormatError, read_npz
from flexparcel.model.model import Model, State

__all__ = [
    "SNAPSHOT_FORMAT",
    "Snapshot",
    "save_snapshot",
    "load_snapshot",
    "place_snapshot",
    "check_snapshot_matches",
    "shipped_snapshot",
    "SHIPPED_SNAPSHOT_DIRS",
    "SnapshotError",
]

SNAPSHOT_FORMAT = 1

SHIPPED_SNAPSHOT_DIRS = tuple(
    Path(__file__).resolve().parents[3] / "data" / f"paper-snapshots-{size}"
    for size in ("10mm", "25mm")
)
"""Where a source checkout keeps the paper consignments' snapshots (``NAME.npz``, made by
``flexparcel assemble NAME``): at the paper's meshes (10 mm, BW 5 mm) and at 25 mm, the
low-fidelity level. An installed wheel has none."""


class SnapshotError(FileFormatError):
    """A snapshot file is unreadable, of another format version, or does not fit the model
    (a :class:`~flexparcel.io.FileFormatError`, hence a ``ValueError``)."""


@dataclass
class Snapshot:
    """A settled consignment (SI units)."""

    build: ConsignmentBuild
    reference_positions: np.ndarray
    """Stress-free node positions of the mesh [m], (n, 3)."""
    positions: np.ndarray
    """Settled positions [m], (n, 3)."""
    rotations: np.ndarray
    """Settled nodal rotation matrices, (n, 3, 3)."""
    info: dict
    """How it was made (assembly settings, kinetic energy at the end, wall time...)."""

    def state(self) -> State:
        """The snapshot as a state at rest at t = 0."""
        n = len(self.positions)
        return State(
            0.0, self.positions.copy(), self.rotations.copy(), np.zeros((n, 6)),
            np.zeros((n, 6)),
        )  # fmt: skip

    def check_fits(self, model: Model, first_node: int = 0) -> None:
        """Raise :class:`SnapshotError` unless ``model`` holds this snapshot's mesh as the
        nodes ``first_node, first_node + 1, ...`` (default: the model's first nodes)."""
        n = len(self.positions)
        k = int(first_node)
        if (
            k < 0
            or model.node_count < k + n
            or not np.array_equal(model.positions0[k : k + n], self.reference_positions)
        ):
            where = f"first {n} nodes" if k == 0 else f"{n} nodes from node {k}"
            raise SnapshotError(
                f"snapshot of {self.build.spec.id!r} does not fit this model (its {where} "
                "must be the snapshot's mesh; was the consignment built with other settings?)"
            )


def save_snapshot(snapshot: Snapshot, path: str | Path) -> Path:
    """Write ``snapshot`` to ``path`` (.npz) atomically; returns the path."""
    meta = {
        "format": SNAPSHOT_FORMAT,
        "flexparcel_version": __version__,
        "build": snapshot.build.to_dict(),
        "info": snapshot.info,
    }
    path = Path(path)

    def write(fh) -> None:
        np.savez(
            fh,
            meta=np.array(json.dumps(meta)),
            reference_positions=snapshot.reference_positions,
            positions=snapshot.positions,
            rotations=snapshot.rotations,
        )

    write_atomic(path, write)
    return path


def load_snapshot(path: str | Path) -> Snapshot:
    """Read a snapshot written by :func:`save_snapshot`.

    Raises :class:`SnapshotError` naming the file for an empty, truncated, damaged or foreign
    file, a missing entry or another format version; ``FileNotFoundError`` for a missing
    file."""
    path = Path(path)
    what = "snapshot"
    data = read_npz(path, what, SnapshotError)
    missing = [k for k in _SNAPSHOT_KEYS if k not in data]
    if missing:
        raise SnapshotError(
            f"{what} {path}: not a flexparcel snapshot (no {', '.join(map(repr, missing))}; "
            "make one with flexparcel assemble)"
        )
    try:
        meta = json.loads(str(data["meta"]))
    except json.JSONDecodeError as exc:
        raise SnapshotError(f"{what} {path}: its 'meta' entry is not valid JSON ({exc})") from exc
    if not isinstance(meta, dict):
        raise SnapshotError(f"{what} {path}: not a flexparcel snapshot (its 'meta' is no table)")
    if meta.get("format") != SNAPSHOT_FORMAT:
        raise SnapshotError(
            f"{what} {path}: snapshot format {meta.get('format')!r}, this flexparcel reads "
            f"format {SNAPSHOT_FORMAT}; assemble the consignment again"
        )
    arrays = {k: data[k] for k in _SNAPSHOT_KEYS[1:]}
    n = len(arrays["positions"])
    shapes = {"reference_positions": (n, 3), "positions": (n, 3), "rotations": (n, 3, 3)}
    for k, shape in shapes.items():
        if arrays[k].shape != shape or not np.issubdtype(arrays[k].dtype, np.floating):
            raise SnapshotError(
                f"{what} {path}: {k} has shape {arrays[k].shape} ({arrays[k].dtype}), "
                f"expected {shape} floats"
            )
    try:
        build = ConsignmentBuild.from_dict(meta["build"])
        info = meta["info"]
    except KeyError as exc:
        raise SnapshotError(f"{what} {path}: its 'meta' has no {exc} entry") from exc
    except (TypeError, ValueError) as exc:
        raise SnapshotError(
            f"{what} {path}: its consignment description is invalid ({exc})"
        ) from exc
    return Snapshot(build, info=info, **arrays)


_SNAPSHOT_KEYS = ("meta", "reference_positions", "positions", "rotations")


def place_snapshot(
    snapshot: Snapshot,
    model: Model,
    *,
    rotation: np.ndarray | None = None,
    lowest_z: float | None = None,
    offset: tuple[float, float, float] = (0.0, 0.0, 0.0),
    first_node: int = 0,
    state: State | None = None,
) -> State:
    """Initial state of ``model`` with the snapshot's nodes moved rigidly: rotated by
    ``rotation`` (3, 3) about the origin, then shifted by ``offset`` [m] and, if ``lowest_z``
    is given, vertically so the lowest packaging node sits at ``lowest_z`` [m].

    The snapshot's mesh is the model's nodes ``first_node .. first_node + n - 1`` (n = the
    snapshot's node count; ``first_node`` is the smallest id of the
    :class:`~flexparcel.consignments.build.Consignment` that :func:`add_consignment` returned
    for it, 0 when it was added first). Nodes outside that range are copied from ``state``
    (e.g. another consignment already placed) or, by default, keep their reference state.
    ``state`` itself is not modified."""
    k = int(first_node)
    snapshot.check_fits(model, k)
    n = len(snapshot.positions)
    r = np.eye(3) if rotation is None else np.asarray(rotation, float)
    if state is None:
        s = model.initial_state()
    else:
        if state.positions.shape != (model.node_count, 3):
            raise ValueError(
                f"place_snapshot: state has {len(state.positions)} nodes, the model "
                f"{model.node_count}"
            )
        s = state.copy()
    sl = slice(k, k + n)
    s.positions[sl] = snapshot.positions @ r.T + np.asarray(offset, float)
    s.rotations[sl] = np.einsum("ij,njk->nik", r, snapshot.rotations)
    if lowest_z is not None:
        s.positions[sl, 2] += lowest_z - s.positions[sl, 2].min()
    return s


def check_snapshot_matches(
    snapshot: Snapshot, build: ConsignmentBuild | None, element_size: float | None
) -> None:
    """Raise ``ValueError`` unless ``snapshot`` was assembled from ``build`` (same spec and
    material, where given) with ``element_size`` [m] (where given)."""
    sb = snapshot.build
    if build is not None:
        if sb.spec != build.spec:
            raise ValueError(
                f"the snapshot holds consignment {sb.spec.id!r} ({sb.spec.packaging_material}, "
                f"{sb.spec.length_mm:g} x {sb.spec.width_mm:g} mm), not the given "
                f"{build.spec.id!r}; leave out --consignment or assemble it again"
            )
        # the provenance text may differ (a renamed file); the numbers must not
        if replace(sb.material, source="") != replace(build.material, source=""):
            raise ValueError(
                f"the snapshot of {sb.spec.id!r} was assembled with another packaging "
                "material; leave out --consignment or assemble it again"
            )
    if element_size is not None and not np.isclose(sb.element_size, element_size):
        raise ValueError(
            f"the snapshot was assembled with {sb.element_size * 1e3:g} mm elements, not "
            f"{element_size * 1e3:g} mm; leave out --element-size or assemble it again"
        )


def shipped_snapshot(build: ConsignmentBuild) -> tuple[Snapshot, Path] | None:
    """The shipped snapshot of ``build`` (:data:`SHIPPED_SNAPSHOT_DIRS`) and its path, when
    one was assembled from this build (spec, material and element size), on today's mesh
    (its reference positions those of the mesh the builder makes now), and passed the
    assembly's rest and shape checks (``info["shape"]`` without failures: a snapshot from
    before the shape check is not taken); else None."""
    from flexparcel.builder import ModelBuilder
    from flexparcel.consignments.build import add_consignment

    for folder in SHIPPED_SNAPSHOT_DIRS:
        path = folder / f"{build.spec.id}.npz"
        if not path.is_file():
            continue
        try:
            snap = load_snapshot(path)
            check_snapshot_matches(snap, build, build.element_size)
        except ValueError:  # SnapshotError is one
            continue
        shape = snap.info.get("shape")
        if not (snap.info.get("at_rest") and isinstance(shape, dict) and not shape["failures"]):
            continue
        b = ModelBuilder()
        add_consignment(b, build)
        model = b.finalize()
        try:
            snap.check_fits(model)
        except SnapshotError:
            continue
        return snap, path
    return None
