"""The checkpoint of an assembly, so that an assembly of hours (KP at the paper's 10 mm: the
closing alone takes some 35 min on the 2-core machine) survives an interruption and resumes
where it stopped, and so that a stalled phase can be studied from the state it started in.

One ``.npz`` file (``allow_pickle=False``, written atomically) holds the assembly's position:
its phase (``"opening"``, ``"closed"`` or ``"settling"``), the state at the end of the last
chunk, the integrator's history there (:meth:`GeneralizedAlpha.history`, so that the
stepper goes on exactly as if uninterrupted), the step count, the time the opening ended and
the wall time spent so far. The closing is one :func:`~flexparcel.simulate.simulate` call;
it resumes from its own run checkpoint beside this file (:meth:`AssemblyCheckpoint.closing_path`).
A JSON header names the consignment, the element size, the settings, the integrator options
and a fingerprint of the opening model (mesh, materials, masses): an assembly resumes only
from a checkpoint of the same assembly, anything else is refused by the field that differs.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from flexparcel.io.atomic import write_atomic
from flexparcel.io.checkpoint import CheckpointError, check_same_run
from flexparcel.io.results import read_npz
from flexparcel.model.model import State

__all__ = ["ASSEMBLY_PHASES", "AssemblyCheckpoint", "AssemblyPosition"]

ASSEMBLY_CHECKPOINT_FORMAT = "flexparcel-assembly-checkpoint"
ASSEMBLY_CHECKPOINT_VERSION = 1
ASSEMBLY_PHASES = ("opening", "closed", "settling")
"""``opening``: within (or at the end of) the opening; ``closed``: the closing has ended;
``settling``: within the settling."""
_STATE_KEYS = ("positions", "rotations", "velocities", "accelerations")


@dataclass
class AssemblyPosition:
    """Where an assembly stands (see the module docstring)."""

    phase: str
    state: State
    history: dict[str, np.ndarray]
    """The phase's integrator history at ``state`` (empty for ``closed``)."""
    steps: int
    """Integration steps of the assembly up to ``state``."""
    t_open: float | None
    """Time [s] the opening ended (None while it runs)."""
    wall_s: float
    """Wall time [s] spent on the assembly up to ``state``, over all its runs."""


class AssemblyCheckpoint:
    """The checkpoint file ``path`` of the assembly that ``header`` describes (JSON-able:
    consignment, element size, settings, options, model fingerprint)."""

    def __init__(self, path: str | Path, header: dict) -> None:
        self.path = Path(path)
        self.header = {
            "format": ASSEMBLY_CHECKPOINT_FORMAT,
            "version": ASSEMBLY_CHECKPOINT_VERSION,
            **json.loads(json.dumps(header)),  # as it reads back from the file
        }

    def closing_path(self) -> Path:
        """The closing's own run checkpoint (:func:`~flexparcel.simulate.simulate`)."""
        return self.path.with_name(self.path.stem + ".closing.npz")

    def load(self) -> AssemblyPosition | None:
        """The position saved in the file, None if there is no file; raises
        :class:`~flexparcel.io.checkpoint.CheckpointError` for a file of another assembly, of
        another format or version, or one that cannot be read."""
        if not self.path.exists():
            return None
        data = read_npz(self.path, "assembly checkpoint", CheckpointError)
        try:
            header = json.loads(str(data["header"]))
            pos = json.loads(str(data["position"]))
            state = State(float(pos["time"]), *(data[f"state_{k}"] for k in _STATE_KEYS))
        except (KeyError, json.JSONDecodeError, TypeError) as exc:
            raise CheckpointError(
                f"assembly checkpoint {self.path}: not a flexparcel assembly checkpoint "
                f"({exc!r}); remove it to start the assembly over"
            ) from None
        check_same_run(self.path, header, self.header)
        if pos.get("phase") not in ASSEMBLY_PHASES:
            raise CheckpointError(
                f"assembly checkpoint {self.path}: phase {pos.get('phase')!r} is not one of "
                f"{', '.join(ASSEMBLY_PHASES)}"
            )
        history = {k[5:]: v for k, v in data.items() if k.startswith("hist_")}
        t_open = pos.get("t_open")
        return AssemblyPosition(pos["phase"], state, history, int(pos["steps"]),
                                None if t_open is None else float(t_open),
                                float(pos["wall_s"]))  # fmt: skip

    def save(self, position: AssemblyPosition) -> None:
        """Write ``position`` atomically (a reader sees the old file or the whole new one)."""
        if position.phase not in ASSEMBLY_PHASES:
            raise ValueError(f"assembly checkpoint: unknown phase {position.phase!r}")
        s = position.state
        pos = {
            "phase": position.phase,
            "time": float(s.time),
            "steps": int(position.steps),
            "t_open": None if position.t_open is None else float(position.t_open),
            "wall_s": float(position.wall_s),
        }
        arrays = {
            "header": np.array(json.dumps(self.header, sort_keys=True)),
            "position": np.array(json.dumps(pos, sort_keys=True)),
        }
        arrays.update({f"state_{k}": np.asarray(getattr(s, k)) for k in _STATE_KEYS})
        arrays.update({f"hist_{k}": np.asarray(v) for k, v in position.history.items()})
        write_atomic(self.path, lambda f: np.savez(f, **arrays))

    def remove(self) -> None:
        """Delete the file and the closing's run checkpoint (the assembly has ended)."""
        for p in (self.path, self.closing_path()):
            p.unlink(missing_ok=True)
