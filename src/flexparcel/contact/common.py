"""Pieces shared by the contact sets: stick-model history and zeroed kernel outputs."""

from __future__ import annotations

import hashlib

import numpy as np

__all__ = [
    "StickAnchors",
    "AnchoredHistory",
    "ElasticSlipHistory",
    "pair_blocks",
    "check_history",
    "set_digest",
]


class StickAnchors:
    """Stick-model history of coupled contacts (node-box pairs, node-face sets): an anchor
    point (3,) per contact and whether it holds one. The kernels read the committed anchors of
    the last accepted step and write each evaluation's anchors to the trial arrays (a contact
    out of touch writes none, so it loses its spring); :meth:`commit` keeps the trial of the
    accepted step."""

    def __init__(self, count: int) -> None:
        self.anchor = np.zeros((count, 3))
        self.has = np.zeros(count)
        self.anchor_trial = np.zeros((count, 3))
        self.has_trial = np.zeros(count)

    def kernel_args(self):
        return self.anchor, self.has, self.anchor_trial, self.has_trial

    def commit(self) -> None:
        # swap, not copy: the kernels rewrite every trial flag at each evaluation, so the old
        # committed arrays can serve as the next trial
        self.anchor, self.anchor_trial = self.anchor_trial, self.anchor
        self.has, self.has_trial = self.has_trial, self.has

    def history(self) -> dict[str, np.ndarray]:
        return {"anchor": self.anchor, "has": self.has}

    def restore(self, history: dict[str, np.ndarray]) -> None:
        self.anchor = check_history(history, "anchor", self.anchor)
        self.has = check_history(history, "has", self.has)


class AnchoredHistory:
    """Mixin of a contact set whose history is its ``anchors`` (:class:`StickAnchors`)."""

    anchors: StickAnchors

    def commit(self) -> None:
        self.anchors.commit()

    def history(self) -> dict[str, np.ndarray]:
        return self.anchors.history()

    def restore_history(self, history) -> None:
        self.anchors.restore(history)


class ElasticSlipHistory:
    """Mixin of a contact set on a rigid plane whose stick model carries an elastic slip
    ``u_el`` (rows, 3) [m] per contact point (node points, edge stations): the kernels read
    the committed ``u_el`` of the last accepted step and write each evaluation's into
    ``u_el_trial``."""

    u_el: np.ndarray
    u_el_trial: np.ndarray

    def _init_elastic_slip(self, rows: int) -> None:
        self.u_el = np.zeros((rows, 3))
        self.u_el_trial = self.u_el.copy()

    def begin_step(self) -> None:
        self.u_el_trial = np.zeros_like(self.u_el)  # points out of contact lose their spring

    def commit(self) -> None:
        self.u_el = self.u_el_trial.copy()

    def history(self) -> dict[str, np.ndarray]:
        return {"u_el": self.u_el}

    def restore_history(self, history) -> None:
        self.u_el = check_history(history, "u_el", self.u_el)


def check_history(history: dict[str, np.ndarray], key: str, like: np.ndarray) -> np.ndarray:
    """``history[key]`` as a fresh array of ``like``'s shape and dtype, else ``ValueError``."""
    if key not in history:
        raise ValueError(f"contact history: missing {key!r}")
    v = np.asarray(history[key])
    if v.shape != like.shape:
        raise ValueError(
            f"contact history: {key!r} has shape {v.shape}, this model needs {like.shape}"
        )
    return v.astype(like.dtype, copy=True)


def pair_blocks(count: int, width: int):
    """Zeroed outputs of a coupled contact kernel: position and velocity blocks (count, width,
    width) and DOF numbers (count, width)."""
    return (np.zeros((count, width, width)), np.zeros((count, width, width)),
            np.zeros((count, width), dtype=np.int64))  # fmt: skip


def set_digest(kind: str, *arrays) -> str:
    """Identity of a contact set's data (node numbers already mapped), for history keys."""
    h = hashlib.sha256(kind.encode())
    for a in arrays:
        a = np.ascontiguousarray(a)
        h.update(str((a.dtype.str, a.shape)).encode())
        h.update(a.tobytes())
    return h.hexdigest()[:32]
