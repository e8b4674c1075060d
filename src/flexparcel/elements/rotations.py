"""Rotation kinematics on SO(3): exponential and logarithm maps and their tangent operators.

The kernels are numba-compiled and dtype-generic: they accept real or complex arrays, so the
element kernels that use them can be differentiated by the complex-step method
(Martins, Sturdza & Alonso 2003, ACM TOMS 29(3)) to machine precision.

Conventions: a rotation vector ``theta`` (3,) [rad] maps to ``R = exp(W(theta))`` with
``W(a) b = a x b``. Variations are *spatial* (left) spins: ``dR R^T = W(dphi)``, and
``dphi = T(theta) dtheta`` with the left Jacobian ``T`` (Simo & Vu-Quoc 1986, eq. 2.12).
"""

from __future__ import annotations

import numba as nb
import numpy as np

__all__ = ["skew", "rotation_exp", "rotation_log", "tangent_inv", "tangent", "matmul"]

# Below this |theta|^2 the closed forms lose digits to cancellation; Taylor series are used.
_SMALL2 = 1e-4


@nb.njit(cache=True)
def matmul(a, b):
    """a @ b by loops: numba's ``@`` calls BLAS, whose call overhead dominates for 3x3 and 18x18
    operands. Both operands must have the same dtype."""
    n, k = a.shape
    m = b.shape[1]
    c = np.zeros((n, m), a.dtype)
    for i in range(n):
        for p in range(k):
            aip = a[i, p]
            if aip != 0.0:
                for j in range(m):
                    c[i, j] += aip * b[p, j]
    return c


@nb.njit(cache=True)
def skew(a):
    """W(a) (3, 3) with W(a) b = a x b."""
    w = np.zeros((3, 3), a.dtype)
    w[0, 1] = -a[2]
    w[0, 2] = a[1]
    w[1, 0] = a[2]
    w[1, 2] = -a[0]
    w[2, 0] = -a[1]
    w[2, 1] = a[0]
    return w


@nb.njit(cache=True)
def rotation_exp(theta):
    """Rodrigues: R = I + sin|t|/|t| W + (1 - cos|t|)/|t|^2 W^2, shape (3, 3)."""
    t2 = theta[0] * theta[0] + theta[1] * theta[1] + theta[2] * theta[2]
    if t2.real < _SMALL2:
        a = 1.0 - t2 / 6.0 + t2 * t2 / 120.0 - t2 * t2 * t2 / 5040.0
        b = 0.5 - t2 / 24.0 + t2 * t2 / 720.0 - t2 * t2 * t2 / 40320.0
    else:
        t = np.sqrt(t2)
        a = np.sin(t) / t
        b = (1.0 - np.cos(t)) / t2
    w = skew(theta)
    r = a * w + b * matmul(w, w)
    for i in range(3):
        r[i, i] += 1.0
    return r


@nb.njit(cache=True)
def rotation_log(r):
    """Rotation vector theta (3,) of a rotation matrix, |theta| <= pi.

    Uses the axial part w = sin|t| n and the trace; both branches are analytic so the
    complex-step derivative is exact. Not defined at |theta| = pi exactly (never needed: element
    rotations relative to their co-rotated frame are small, and step increments are small).
    """
    w = np.zeros(3, r.dtype)
    w[0] = 0.5 * (r[2, 1] - r[1, 2])
    w[1] = 0.5 * (r[0, 2] - r[2, 0])
    w[2] = 0.5 * (r[1, 0] - r[0, 1])
    s2 = w[0] * w[0] + w[1] * w[1] + w[2] * w[2]
    tr = r[0, 0] + r[1, 1] + r[2, 2]
    if tr.real >= 1.0:  # |theta| <= pi/2: theta = asin(s)
        if s2.real < _SMALL2:
            f = 1.0 + s2 / 6.0 + 3.0 * s2 * s2 / 40.0 + 5.0 * s2 * s2 * s2 / 112.0
        else:
            s = np.sqrt(s2)
            f = np.arcsin(s) / s
    else:  # |theta| > pi/2: theta = pi - asin(s)
        s = np.sqrt(s2)
        f = (np.pi - np.arcsin(s)) / s
    return f * w


@nb.njit(cache=True)
def tangent_inv(theta):
    """Inverse left Jacobian: T^-1 = I - W/2 + (1 - (t/2) cot(t/2)) / t^2 W^2, shape (3, 3)."""
    t2 = theta[0] * theta[0] + theta[1] * theta[1] + theta[2] * theta[2]
    if t2.real < _SMALL2:
        c = 1.0 / 12.0 + t2 / 720.0 + t2 * t2 / 30240.0
    else:
        t = np.sqrt(t2)
        c = (1.0 - 0.5 * t * np.cos(0.5 * t) / np.sin(0.5 * t)) / t2
    w = skew(theta)
    m = -0.5 * w + c * matmul(w, w)
    for i in range(3):
        m[i, i] += 1.0
    return m


@nb.njit(cache=True)
def tangent(theta):
    """Left Jacobian T = I + (1 - cos t)/t^2 W + (t - sin t)/t^3 W^2, shape (3, 3)."""
    t2 = theta[0] * theta[0] + theta[1] * theta[1] + theta[2] * theta[2]
    if t2.real < _SMALL2:
        a = 0.5 - t2 / 24.0 + t2 * t2 / 720.0
        b = 1.0 / 6.0 - t2 / 120.0 + t2 * t2 / 5040.0
    else:
        t = np.sqrt(t2)
        a = (1.0 - np.cos(t)) / t2
        b = (t - np.sin(t)) / (t2 * t)
    w = skew(theta)
    m = a * w + b * matmul(w, w)
    for i in range(3):
        m[i, i] += 1.0
    return m


@nb.njit(cache=True)
def apply_spins(rot, spins):
    """In place: ``rot[i] <- exp(spins[i]) rot[i]`` for every node with a non-zero spin.
    ``rot`` (n, 3, 3), ``spins`` (n, 3) [rad]."""
    for i in range(rot.shape[0]):
        if spins[i, 0] != 0.0 or spins[i, 1] != 0.0 or spins[i, 2] != 0.0:
            rot[i] = matmul(rotation_exp(spins[i].copy()), rot[i].copy())


@nb.njit(cache=True)
def relative_rotation_vectors(rot, rot_ref):
    """``log(rot[i] rot_ref[i]^T)`` for all nodes, shape (n, 3)."""
    out = np.zeros((rot.shape[0], 3))
    for i in range(rot.shape[0]):
        out[i] = rotation_log(matmul(rot[i].copy(), rot_ref[i].T.copy()))
    return out


@nb.njit(cache=True)
def rotation_vectors(rot):
    """``log(rot[i])`` for all nodes, shape (n, 3)."""
    out = np.zeros((rot.shape[0], 3))
    for i in range(rot.shape[0]):
        out[i] = rotation_log(rot[i].copy())
    return out
