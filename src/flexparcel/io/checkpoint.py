"""Checkpoints of a running simulation, so that a long run (hours for the 2 s conveyor) survives
an interruption and resumes where it stopped.

A checkpoint is one ``.npz`` file (``allow_pickle=False``, written atomically): the frames
recorded so far, the state at the last frame, the integrator's history
(:meth:`flexparcel.integrate.dynamic.GeneralizedAlpha.history`) and a JSON header that says
which run it belongs to: format version, start and end time, output interval, integrator
options, and SHA-256 fingerprints of the model and of the initial state. A run resumes only
from a checkpoint of the same run; anything else is refused with the field that differs.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from flexparcel.io.atomic import write_atomic
from flexparcel.io.results import FileFormatError, read_npz
from flexparcel.model.model import Model, State

__all__ = [
    "CHECKPOINT_FORMAT",
    "CHECKPOINT_VERSION",
    "CheckpointError",
    "MONITORED_FRAME_KEY",
    "RunCheckpoint",
    "check_same_run",
    "model_fingerprint",
    "state_fingerprint",
    "load_checkpoint",
    "save_checkpoint",
]

CHECKPOINT_FORMAT = "flexparcel-run-checkpoint"
CHECKPOINT_VERSION = 2  # 2: contact history keyed by contact set

# the arrays that define a model's dynamics (geometry, mass, supports, bodies); the element
# groups and contact sets add their own (fingerprint_arrays)
_MODEL_FIELDS = (
    "positions0", "mass", "fixed", "gravity", "mass_damping", "rigid_nodes", "rigid_inertia",
    "plane_point", "plane_normal", "plane_velocity", "contact_laws", "prescribed_nodes",
    "prescribed_velocity",
)  # fmt: skip


class CheckpointError(FileFormatError):
    """A checkpoint file that cannot be read or belongs to another run (a
    :class:`~flexparcel.io.FileFormatError`, hence a ``ValueError``)."""


def _digest(arrays) -> str:
    h = hashlib.sha256()
    for a in arrays:
        a = np.ascontiguousarray(np.asarray(a))
        h.update(str((a.dtype.str, a.shape)).encode())
        h.update(a.tobytes())
    return h.hexdigest()


def model_fingerprint(model: Model) -> str:
    """SHA-256 over the arrays that define the model's dynamics (hex)."""
    arrays = [getattr(model, k) for k in _MODEL_FIELDS]
    if model.plane_extent.any():  # bounded planes only: half-spaces keep their digests
        arrays += [model.plane_axis, model.plane_extent]
    for part in (*model.element_groups, *model.contact_sets):
        arrays.extend(part.fingerprint_arrays())
    return _digest(arrays)


def state_fingerprint(state: State) -> str:
    """SHA-256 over a state's time, positions, rotations and velocities (hex)."""
    return _digest([np.array(state.time), state.positions, state.rotations, state.velocities])


@dataclass
class RunCheckpoint:
    """What a checkpoint file holds (see the module docstring)."""

    header: dict
    """format, version, t0, t_end, dt_out, node_count, model, initial_state (fingerprints),
    options (dict), complete (bool)."""
    frames: dict[str, np.ndarray]
    """Recorded so far: ``time`` (k,), ``positions`` (k, n, 3), ``rotation_vectors``
    (k, n, 3), ``velocities`` (k, n, 6), ``energies`` (k, 3) [J] (kinetic, strain, gravity)."""
    state: State
    """The state at the last recorded frame."""
    history: dict[str, np.ndarray]
    """The integrator's history at that state."""


_FRAME_KEYS = ("time", "positions", "rotation_vectors", "velocities", "energies")
_STATE_KEYS = ("positions", "rotations", "velocities", "accelerations")
MONITORED_FRAME_KEY = "monitored_impulses"
"""Frames of a model with monitored contacts also hold their impulse on every node."""


def save_checkpoint(path: str | Path, ckpt: RunCheckpoint) -> Path:
    """Write ``ckpt`` to ``path`` (.npz) atomically; returns the path."""
    arrays = {"header": np.array(json.dumps(ckpt.header, sort_keys=True))}
    arrays.update({f"frame_{k}": np.asarray(ckpt.frames[k]) for k in _FRAME_KEYS})
    if MONITORED_FRAME_KEY in ckpt.frames:
        arrays[f"frame_{MONITORED_FRAME_KEY}"] = np.asarray(ckpt.frames[MONITORED_FRAME_KEY])
    arrays["state_time"] = np.array(float(ckpt.state.time))
    arrays.update({f"state_{k}": getattr(ckpt.state, k) for k in _STATE_KEYS})
    arrays.update({f"hist_{k}": v for k, v in ckpt.history.items()})

    def write(f) -> None:
        np.savez(f, **arrays)

    return write_atomic(path, write)


def load_checkpoint(path: str | Path) -> RunCheckpoint:
    """Read a checkpoint written by :func:`save_checkpoint`; raises :class:`CheckpointError`
    naming the file for anything unreadable, of another format or of another version."""
    path = Path(path)
    data = read_npz(path, "checkpoint", CheckpointError)
    if "header" not in data:  # an .npz of something else: say what it holds
        held = ", ".join(sorted(data)[:4]) or "nothing"
        raise CheckpointError(
            f"checkpoint {path}: not a flexparcel checkpoint (no 'header' entry; it holds "
            f"{held}); flexparcel run conveyor and simulate(checkpoint=...) write them"
        )
    try:
        header = json.loads(str(data["header"]))
    except json.JSONDecodeError as e:
        raise CheckpointError(f"checkpoint {path}: its header is not valid JSON ({e})") from e
    if not isinstance(header, dict) or header.get("format") != CHECKPOINT_FORMAT:
        raise CheckpointError(f"checkpoint {path}: not a {CHECKPOINT_FORMAT} file")
    if header.get("version") != CHECKPOINT_VERSION:
        raise CheckpointError(
            f"checkpoint {path}: version {header.get('version')!r}, this flexparcel reads "
            f"version {CHECKPOINT_VERSION}; remove it to start the run over"
        )
    try:
        frames = {k: data[f"frame_{k}"] for k in _FRAME_KEYS}
        if f"frame_{MONITORED_FRAME_KEY}" in data:  # a model with monitored contacts
            frames[MONITORED_FRAME_KEY] = data[f"frame_{MONITORED_FRAME_KEY}"]
        state = State(float(data["state_time"]), *(data[f"state_{k}"] for k in _STATE_KEYS))
    except KeyError as e:
        raise CheckpointError(f"checkpoint {path}: missing array {e}") from e
    history = {k[5:]: v for k, v in data.items() if k.startswith("hist_")}
    return RunCheckpoint(header, frames, state, history)


def check_same_run(path: str | Path, header: dict, expected: dict) -> None:
    """Raise :class:`CheckpointError` naming the first header field of ``expected`` that
    ``header`` does not match (the checkpoint belongs to another run)."""
    for key, want in expected.items():
        got = header.get(key)
        if got != want:
            if isinstance(want, str) and len(want) == 64:  # a fingerprint
                what = f"another {key.replace('_', ' ')}"
            else:
                what = f"{key} = {got!r}, this run has {key} = {want!r}"
            raise CheckpointError(
                f"checkpoint {path}: written for {what}; remove it (or pick another "
                "checkpoint path) to start this run over"
            )
