"""Flat views of a model's contact sets of one kind, for tests that inspect what a scene
builder set up (e.g. which nodes touch the belt, with which law)."""

from types import SimpleNamespace

import numpy as np

from flexparcel.contact.faces import NodeFaceSet
from flexparcel.contact.planes import PlanePointSet


def plane_points(model) -> SimpleNamespace:
    """All plane contact points: ``node``, ``offset`` (P, 3) [m], ``radius`` [m], ``plane``,
    ``law`` (row of ``model.contact_laws``), each concatenated over the plane sets."""
    sets = [cs for cs in model.contact_sets if isinstance(cs, PlanePointSet)]

    def cat(get, empty):
        return np.concatenate([get(cs) for cs in sets]) if sets else empty

    return SimpleNamespace(
        node=cat(lambda cs: cs.node, np.zeros(0, np.int64)),
        offset=cat(lambda cs: cs.offset, np.zeros((0, 3))),
        radius=cat(lambda cs: cs.radius, np.zeros(0)),
        plane=cat(lambda cs: np.full(cs.node.size, cs.plane), np.zeros(0, np.int64)),
        law=cat(lambda cs: np.full(cs.node.size, cs.law_index), np.zeros(0, np.int64)),
    )


def node_face_sets(model) -> list[tuple[np.ndarray, np.ndarray]]:
    """(nodes (N,), triangles (M, 3)) of each node-to-face contact set."""
    return [(cs.node, cs.triangles) for cs in model.contact_sets if isinstance(cs, NodeFaceSet)]
