"""Responses of a conveyor run, per consignment: trajectory, exit, yaw, deflector contact, jams.

A consignment is a set of node ids (its packaging shell nodes, a rigid content's node, or
both); its position is the centroid (plain mean) of those nodes. Everything is computed from the
recorded output frames of a :class:`flexparcel.SimulationResult`, so time resolution is the
output interval ``dt_out`` of the run.

Definitions (SI units; angles in degrees):

* trajectory: time and centroid x, y, z at every output frame.
* exit: the first time the centroid reaches x = ``scene.exit_x`` (the last belt's end),
  linearly interpolated between the two frames around it, and the centroid there; None if it
  never does.
* yaw: rotation about z since the first frame, from the principal axis of the nodes' x-y
  scatter (the long side of a flat consignment). The axis has no head or tail, so angles are
  unwrapped modulo 180 deg: the consignment must turn less than 90 deg between frames. None
  for a node set without a clear long axis in some frame (in-plane anisotropy
  (l1 - l2) / (l1 + l2) of the scatter's eigenvalues below 2 %, e.g. a single node or a
  square), where the axis is ill-defined.
* deflector contact duration: total time during which *any* node of the set lies within
  ``contact_distance`` of the deflector's face rectangle (not its unbounded plane), whatever the
  centroid does; the in/out indicator is integrated with the trapezoidal rule, so each contact
  episode is accurate to about one output interval. Choose ``contact_distance`` above the
  contact thickness (shell nodes rest about half a shell thickness off the face; a rigid
  body's node sits half the box width off it). The first contact is the first frame with a
  node that close. In ``responses.json`` both are null for a deflector never touched (a
  duration of 0.0 s read as "contact at t = 0").
* jam: the first frame time t0 (not after exit) after which the centroid gets no further than
  ``jam_distance`` beyond x(t0) during ``jam_time``; None if there is none. Windows that run
  past the end of the record are not judged, so a jam in the last ``jam_time`` of a run goes
  unreported; :meth:`ConsignmentResponse.jam_verdict` says which case a None is.
* contact force: a force time series the caller supplies per consignment, shape (k,) or
  (k, 3) [N], kept as its magnitude (k,); its peak and the peak's time; None when not
  supplied. :func:`~flexparcel.scenarios.conveyor_scene.run_conveyor` supplies the
  deflectors' mean force over the output interval that ends at each frame (from the
  recorded impulse), so the peak's time is the end of that interval.

``responses.json`` (:meth:`ConsignmentResponse.to_dict`) names every quantity with its unit
(``_s``, ``_m``, ``_deg``, ``_N``) and gives a note for every null.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from flexparcel.scenarios.conveyor import ConveyorScene

if TYPE_CHECKING:
    from flexparcel.simulate import SimulationResult

__all__ = ["ConsignmentResponse", "conveyor_responses"]

# Below this in-plane anisotropy of the node scatter the principal axis is ill-defined (and
# sensitive to tiny deformations), so yaw is not reported.
_MIN_ANISOTROPY = 0.02


@dataclass(frozen=True, eq=False)
class ConsignmentResponse:
    """Responses of one consignment (see the module docstring for definitions)."""

    name: str
    time: np.ndarray
    """Output times [s], shape (k,)."""
    centroid: np.ndarray
    """Centroid of the node set [m], shape (k, 3)."""
    yaw_deg: np.ndarray | None
    """Rotation about z since the first frame [deg], shape (k,), or None."""
    exit_time: float | None
    """Time the centroid reaches the belt end [s], or None."""
    exit_position: np.ndarray | None
    """Centroid at ``exit_time`` [m], shape (3,), or None."""
    deflector_contact_time: tuple[float, ...]
    """Time in contact with each deflector of the scene [s] (a duration; 0.0: never)."""
    jam_start: float | None
    """Start of the first jam [s], or None."""
    peak_contact_force: float | None = None
    """Largest supplied contact force magnitude [N], or None."""
    peak_contact_force_time: float | None = None
    """Its time [s], or None."""
    deflector_first_contact: tuple[float | None, ...] = ()
    """First frame time [s] in contact with each deflector, None where never."""
    contact_force: np.ndarray | None = None
    """Magnitude of the supplied contact force at each frame [N], shape (k,), or None."""
    jam_time: float = 0.3
    """Length of the jam window [s]."""
    jam_distance: float = 5e-3
    """Progress along x below which a window counts as jammed [m]."""
    contact_distance: float = 2e-3
    """Node-to-face distance counted as deflector contact [m]."""

    def jam_verdict(self) -> tuple[str, str]:
        """``(state, sentence)``: state ``"jam"`` (from :attr:`jam_start`), ``"left"`` (left
        the belt before a window showed a jam), ``"none"`` (every window that fits in the run
        judged, no jam) or ``"not judged"`` (the run is shorter than one window)."""
        window = f"{1e3 * self.jam_distance:g} mm in {self.jam_time:g} s"
        t0, t1 = float(self.time[0]), float(self.time[-1])
        if self.jam_start is not None:
            return "jam", f"jammed from t = {self.jam_start:.3f} s (advanced less than {window})"
        if self.exit_time is not None:
            return "left", f"no jam: left the belt at t = {self.exit_time:.3f} s"
        last = t1 - self.jam_time
        if last < t0:
            return "not judged", (f"not reached in this run: the run ({t1 - t0:.3g} s) is "
                                  f"shorter than the {self.jam_time:g} s jam window")  # fmt: skip
        return "none", (f"no jam: never less than {window} in the windows starting up to "
                        f"t = {last:.3f} s (later ones run past the end)")  # fmt: skip

    def notes(self) -> dict[str, str]:
        """Why each null of :meth:`to_dict` is null (key -> sentence); empty where none is."""
        out = {}
        if self.exit_time is None:
            out["exit_time_s"] = "did not reach the belt end within the run"
            out["exit_position_m"] = out["exit_time_s"]
        never = [str(i) for i, v in enumerate(self.deflector_contact_time, 1) if v <= 0.0]
        if never:
            why = (f"null: no node came within {1e3 * self.contact_distance:g} mm of the "
                   f"face of deflector {', '.join(never)} within the run")  # fmt: skip
            out["deflector_contact_duration_s"] = why
            out["deflector_first_contact_s"] = why
        if self.jam_start is None:
            out["jam_start_s"] = self.jam_verdict()[1]
        if self.yaw_deg is None:
            out["yaw_deg"] = "the node set has no clear long axis in some frame"
        if self.contact_force is None:
            for key in ("contact_force_N", "peak_contact_force_N", "peak_contact_force_time_s"):
                out[key] = "no contact force recorded"
        return out

    def to_dict(self) -> dict:
        """JSON-ready copy: floats, lists and None only; keys carry their unit, ``notes``
        says why a value is null."""

        def opt(v):
            return None if v is None else float(v)

        never = [v <= 0.0 for v in self.deflector_contact_time]
        first = self.deflector_first_contact or (None,) * len(never)
        return {
            "name": self.name,
            "trajectory": {
                "t_s": self.time.tolist(),
                "x_m": self.centroid[:, 0].tolist(),
                "y_m": self.centroid[:, 1].tolist(),
                "z_m": self.centroid[:, 2].tolist(),
            },
            "yaw_deg": None if self.yaw_deg is None else self.yaw_deg.tolist(),
            "contact_force_N": None if self.contact_force is None else self.contact_force.tolist(),
            "exit_time_s": opt(self.exit_time),
            "exit_position_m": (
                None if self.exit_position is None else self.exit_position.tolist()
            ),
            # null, not 0.0, for a deflector never touched (0.0 read as contact at t = 0)
            "deflector_contact_duration_s": [
                None if n else float(v)
                for v, n in zip(self.deflector_contact_time, never, strict=True)
            ],
            "deflector_first_contact_s": [opt(v) for v in first],
            "jam_start_s": opt(self.jam_start),
            "jam_verdict": self.jam_verdict()[1],
            "peak_contact_force_N": opt(self.peak_contact_force),
            "peak_contact_force_time_s": opt(self.peak_contact_force_time),
            "notes": self.notes(),
        }


def _exit(t: np.ndarray, c: np.ndarray, x_end: float) -> tuple[float | None, np.ndarray | None]:
    past = np.flatnonzero(c[:, 0] >= x_end)
    if past.size == 0:
        return None, None
    i = int(past[0])
    if i == 0:
        return float(t[0]), c[0].copy()
    f = (x_end - c[i - 1, 0]) / (c[i, 0] - c[i - 1, 0])
    return float(t[i - 1] + f * (t[i] - t[i - 1])), c[i - 1] + f * (c[i] - c[i - 1])


def _yaw(p: np.ndarray) -> np.ndarray | None:
    """``p`` node positions (k, m, 3) -> rotation about z since frame 0 [deg] (k,) or None."""
    xy = p[:, :, :2] - p[:, :, :2].mean(axis=1, keepdims=True)
    cxx = np.mean(xy[:, :, 0] ** 2, axis=1)
    cyy = np.mean(xy[:, :, 1] ** 2, axis=1)
    cxy = np.mean(xy[:, :, 0] * xy[:, :, 1], axis=1)
    spread = np.hypot(cxx - cyy, 2.0 * cxy)  # l1 - l2 of the 2x2 scatter matrix
    trace = cxx + cyy
    if np.any(spread <= _MIN_ANISOTROPY * trace) or np.any(trace <= 0.0):
        return None
    # twice the major-axis angle is a proper angle (no 180 deg ambiguity): unwrap it, halve it
    two_phi = np.unwrap(np.arctan2(2.0 * cxy, cxx - cyy))
    return np.degrees(0.5 * (two_phi - two_phi[0]))


def _jam(
    t: np.ndarray, x: np.ndarray, exit_time: float | None, distance: float, duration: float
) -> float | None:
    eps = 1e-9 * max(1.0, abs(float(t[-1])))
    for i in range(len(t)):
        end = t[i] + duration
        if end > t[-1] + eps:
            return None  # the window is not fully recorded
        if exit_time is not None and exit_time <= end:
            return None  # it leaves the belt within (or before) the window
        j = int(np.searchsorted(t, end + eps, side="right"))
        if x[i:j].max() - x[i] <= distance:
            return float(t[i])
    return None


def _deflector_contact(
    t: np.ndarray, p: np.ndarray, deflectors, distance: float
) -> tuple[tuple[float, ...], tuple[float | None, ...]]:
    """Contact duration [s] and first contact time [s] (None: never) with each deflector of
    nodes ``p`` (k, m, 3)."""
    durations, first = [], []
    for g in deflectors:
        inside = g.distance(p).min(axis=1) <= distance
        f = inside.astype(float)
        durations.append(float(np.sum(0.5 * (f[1:] + f[:-1]) * np.diff(t))))
        first.append(float(t[np.argmax(inside)]) if inside.any() else None)
    return tuple(durations), tuple(first)


def _force_magnitude(name: str, f, k: int) -> np.ndarray | None:
    """|force| [N] (k,) of a series of shape (k,) or (k, 3), or None for none."""
    if f is None:
        return None
    f = np.asarray(f, dtype=float)
    if f.shape not in ((k,), (k, 3)):
        raise ValueError(
            f"conveyor_responses: contact_forces[{name!r}] must have shape ({k},) or "
            f"({k}, 3), got {f.shape}"
        )
    return np.abs(f) if f.ndim == 1 else np.linalg.norm(f, axis=1)


def _node_set(name: str, ids, n: int) -> np.ndarray:
    a = np.atleast_1d(np.asarray(ids))
    if a.size == 0 or not np.issubdtype(a.dtype, np.integer):
        raise ValueError(f"consignment {name!r}: node ids must be a non-empty integer array")
    a = a.ravel().astype(np.int64)
    bad = a[(a < 0) | (a >= n)]
    if bad.size:
        raise ValueError(f"consignment {name!r}: node id {int(bad[0])} outside [0, {n - 1}]")
    return a


def conveyor_responses(
    result: SimulationResult,
    consignments: Mapping[str, Sequence[int] | np.ndarray],
    scene: ConveyorScene,
    *,
    contact_distance: float = 2e-3,
    jam_distance: float = 5e-3,
    jam_time: float = 0.3,
    contact_forces: Mapping[str, np.ndarray] | None = None,
) -> dict[str, ConsignmentResponse]:
    """Responses of each consignment of a conveyor run.

    Args:
        result: a :class:`flexparcel.SimulationResult` (only ``time`` (k,) [s] and
            ``positions`` (k, n, 3) [m] are used; any object with them will do).
        consignments: name -> node ids of the consignment, shape (m,).
        scene: the :class:`ConveyorScene` of the run (belt end and deflector faces).
        contact_distance: node-to-deflector-face distance counted as contact [m], > 0.
        jam_distance: progress along x below which a window counts as jammed [m], > 0.
        jam_time: length of that window [s], > 0.
        contact_forces: optional name -> force time series [N], shape (k,) or (k, 3).

    Returns: name -> :class:`ConsignmentResponse`, in the order of ``consignments``.
    """
    t = np.asarray(result.time, dtype=float)
    pos = np.asarray(result.positions, dtype=float)
    if t.ndim != 1 or t.size < 2 or pos.shape[:1] != t.shape or pos.ndim != 3:
        raise ValueError(
            "conveyor_responses: need time (k>=2,) and positions (k, n, 3), got "
            f"{t.shape} and {pos.shape}"
        )
    if not np.all(np.diff(t) > 0.0):
        raise ValueError("conveyor_responses: time must be strictly increasing")
    if not isinstance(scene, ConveyorScene):
        raise TypeError(f"conveyor_responses: scene must be a ConveyorScene, got {type(scene)}")
    for name, v in (
        ("contact_distance", contact_distance),
        ("jam_distance", jam_distance),
        ("jam_time", jam_time),
    ):
        if not (np.isfinite(v) and v > 0.0):
            raise ValueError(f"conveyor_responses: {name} must be > 0, got {v!r}")
    forces = dict(contact_forces or {})
    unknown = sorted(set(forces) - set(consignments))
    if unknown:
        raise ValueError(
            f"conveyor_responses: contact_forces for unknown consignment(s) {unknown}; "
            f"consignments: {list(consignments)}"
        )
    deflectors = scene.deflectors()
    out: dict[str, ConsignmentResponse] = {}
    for name, ids in consignments.items():
        nodes = _node_set(name, ids, pos.shape[1])
        p = pos[:, nodes]  # (k, m, 3)
        c = p.mean(axis=1)
        exit_time, exit_pos = _exit(t, c, scene.exit_x)
        contact, first = _deflector_contact(t, p, deflectors, contact_distance)
        mag = _force_magnitude(name, forces.get(name), len(t))
        peak = peak_t = None
        if mag is not None:
            i = int(np.argmax(mag))
            peak, peak_t = float(mag[i]), float(t[i])
        out[name] = ConsignmentResponse(
            name=str(name),
            time=t.copy(),
            centroid=c,
            yaw_deg=_yaw(p),
            exit_time=exit_time,
            exit_position=exit_pos,
            deflector_contact_time=tuple(contact),
            jam_start=_jam(t, c[:, 0], exit_time, jam_distance, jam_time),
            peak_contact_force=peak,
            peak_contact_force_time=peak_t,
            deflector_first_contact=first,
            contact_force=mag,
            jam_time=float(jam_time),
            jam_distance=float(jam_distance),
            contact_distance=float(contact_distance),
        )
    return out
