"""Thin launchers around the element kernels: global force vectors and tangent matrices.

Arrays are per node, ``(node_count, 6)`` = ``[fx, fy, fz, mx, my, mz]``; matrices are CSR over
the free DOFs of the model (see ``Model.free_index``).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from flexparcel.elements import shell
from flexparcel.elements.rotations import skew
from flexparcel.model.builder import Model

__all__ = [
    "internal_forces",
    "internal_forces_and_tangent",
    "external_forces",
    "add_follower_tangent",
    "csr_from_data",
    "free_vector",
    "kinetic_energy",
    "rigid_inertial_moments",
    "add_rigid_inertia_tangent",
]


def _shell_data(model: Model) -> tuple:
    """The static per-triangle arrays every shell kernel takes first."""
    return model.triangles, model.tri_kl, model.tri_xloc, model.tri_frame0, model.tri_beta


def internal_forces(model: Model, positions, rotations, velocities) -> tuple[np.ndarray, float]:
    """Internal (elastic + Rayleigh damping) nodal forces (n, 6) [N, N m] and strain energy [J]."""
    out = np.zeros((model.node_count, 6))
    energy = shell.element_forces(*_shell_data(model), positions, rotations, velocities, out)
    return out, energy


def internal_forces_and_tangent(
    model: Model, positions, rotations, velocities, consistent: bool = True
) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """Forces (n, 6), CSR data (nnz + 1,) of the stiffness ``K = dF/dq`` and of the damping
    ``C = dF/dv``, and the strain energy [J]. ``consistent=False`` gives the material
    stiffness ``B^T K_l B`` instead of the exact (complex-step) derivative.

    The last data entry is a trash slot collecting fixed-DOF entries; drop it with
    :func:`csr_from_data`.
    """
    out = np.zeros((model.node_count, 6))
    data_k = np.zeros(model.nnz + 1)
    data_c = np.zeros(model.nnz + 1)
    kernel = shell.element_tangents if consistent else shell.material_tangents
    energy = kernel(
        *_shell_data(model),
        positions,
        rotations,
        velocities,
        out,
        data_k,
        data_c,
        model.tri_emap,
    )
    return out, data_k, data_c, energy


def external_forces(model: Model, time: float, rotations: np.ndarray, scale: float = 1.0):
    """External nodal loads (n, 6) at ``time`` [s]: gravity on the lumped masses plus nodal
    forces and moments (follower ones rotated by their node's rotation), times ``scale``."""
    f = np.zeros((model.node_count, 6))
    g = model.gravity * model.gravity_schedule(time)
    f[:, :3] = model.mass[:, :3] * g
    if model.load_nodes.size:
        fac = np.array([s(time) for s in model.schedules])[model.load_schedule]
        vec = model.load_vectors * fac[:, None]
        fol = model.load_follower
        if np.any(fol):
            vec[fol] = np.einsum("kij,kj->ki", rotations[model.load_nodes[fol]], vec[fol])
        mom = model.load_is_moment
        np.add.at(f[:, :3], model.load_nodes[~mom], vec[~mom])
        np.add.at(f[:, 3:], model.load_nodes[mom], vec[mom])
    return f * scale


def add_follower_tangent(model: Model, data: np.ndarray, time: float, rotations, scale=1.0):
    """Add ``-d f_ext / d spin`` of follower loads to CSR ``data`` (residual f_int - f_ext).

    A follower load ``R v0`` varies as ``dphi x (R v0) = -W(R v0) dphi``, so the residual gains
    ``+W(R v0)`` in the (load rows, spin columns) block of its node.
    """
    if not np.any(model.load_follower):
        return
    for k in np.flatnonzero(model.load_follower):
        node = model.load_nodes[k]
        fac = model.schedules[model.load_schedule[k]](time) * scale
        w = skew(rotations[node] @ model.load_vectors[k] * fac)
        blk = 1 if model.load_is_moment[k] else 0
        np.add.at(data, model.load_emap[k, blk].ravel(), w.ravel())


def csr_from_data(model: Model, data: np.ndarray) -> sp.csr_matrix:
    n = model.dof_count
    return sp.csr_matrix((data[:-1], model.csr_indices, model.csr_indptr), shape=(n, n))


def free_vector(model: Model, nodal: np.ndarray) -> np.ndarray:
    """The free-DOF entries of a per-node array (n, 6)."""
    return nodal.ravel()[model.free_index >= 0]


def kinetic_energy(model: Model, velocities: np.ndarray, rotations: np.ndarray) -> float:
    """0.5 v^T M v [J]: lumped nodal masses and isotropic rotary inertia, plus each rigid
    body's 0.5 w^T J_s w with the spatial inertia J_s = R J_body R^T."""
    e = 0.5 * float(np.sum(model.mass * velocities * velocities))
    for k, node in enumerate(model.rigid_nodes):
        r = rotations[node]
        w = velocities[node, 3:]
        e += 0.5 * float(w @ (r @ model.rigid_inertia[k] @ r.T) @ w)
    return e


def rigid_inertial_moments(model: Model, rotations, omega_dot, omega) -> np.ndarray:
    """Euler's equations in spatial form, d(J_s w)/dt = J_s w' + w x (J_s w), for every rigid
    body, as a per-node array (n, 6) (zero outside the bodies' rotation rows)."""
    out = np.zeros((model.node_count, 6))
    for k, node in enumerate(model.rigid_nodes):
        r = rotations[node]
        js = r @ model.rigid_inertia[k] @ r.T
        w = omega[node]
        out[node, 3:] = js @ omega_dot[node] + np.cross(w, js @ w)
    return out


def add_rigid_inertia_tangent(model: Model, data, rotations, omega, ca: float, cv: float):
    """Add ``ca J_s + cv (W(w) J_s - W(J_s w))`` (derivative of the Euler terms through the
    angular acceleration and velocity) to each free body's rotation block; the O(|dtheta|)
    change of J_s with the rotation itself is left out (it vanishes as h -> 0)."""
    for k, node in enumerate(model.rigid_nodes):
        r = rotations[node]
        js = r @ model.rigid_inertia[k] @ r.T
        w = omega[node]
        blk = ca * js + cv * (skew(w) @ js - skew(js @ w))
        np.add.at(data, model.rigid_rot_slots[k].ravel(), blk.ravel())
