"""Rotations and unit quaternions (w, x, y, z), in one place: scipy's ``Rotation``/``Slerp`` where they do the
job, plain numpy where a same-run benchmark shows scipy is too slow for a per-sample series (which function is
which, and the figures: docs/decisions/007). :func:`make_sign_continuous` keeps a series from jumping between
q and −q. All functions take arrays of shape (…, 4) for quaternions and (…, 3, 3) for matrices unless stated."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation, Slerp


def quat_wxyz_from_matrix(R: np.ndarray) -> np.ndarray:
    """Unit quaternions (…, 4) w, x, y, z from rotation matrices (…, 3, 3); w >= 0 (Shepperd's method).

    All four of Shepperd's candidates are computed element-wise and the best-conditioned one (largest
    pivot) is selected per row: no gathers, so it is fast on long series.
    """
    R = np.asarray(R, dtype=np.float64)
    shape = R.shape[:-2]
    R = R.reshape(-1, 3, 3)
    m00, m01, m02 = R[:, 0, 0], R[:, 0, 1], R[:, 0, 2]
    m10, m11, m12 = R[:, 1, 0], R[:, 1, 1], R[:, 1, 2]
    m20, m21, m22 = R[:, 2, 0], R[:, 2, 1], R[:, 2, 2]
    tr = m00 + m11 + m22
    cand = np.stack([tr, m00, m11, m22])
    k = np.argmax(cand, axis=0)
    r = np.sqrt(np.maximum(1.0 + 2.0 * np.take_along_axis(cand, k[None], 0)[0] - tr, 1e-300))
    s = 0.5 / r
    a, b, c = (m21 - m12) * s, (m02 - m20) * s, (m10 - m01) * s  # 4w·(x, y, z) / (4·pivot)
    d, e, f = (m01 + m10) * s, (m02 + m20) * s, (m12 + m21) * s  # 4xy, 4xz, 4yz / (4·pivot)
    h = 0.5 * r
    table = np.stack(
        [
            np.stack([h, a, b, c]),  # pivot w
            np.stack([a, h, d, e]),  # pivot x
            np.stack([b, d, h, f]),  # pivot y
            np.stack([c, e, f, h]),  # pivot z
        ]
    )  # (4 cases, 4 components, N)
    q = np.take_along_axis(table, k[None, None, :], 0)[0].T
    q = q * np.where(q[:, :1] < 0, -1.0, 1.0)
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    return q.reshape(*shape, 4)


def matrix_from_quat_wxyz(q: np.ndarray) -> np.ndarray:
    """Rotation matrices (…, 3, 3) from quaternions (…, 4) w, x, y, z (normalised first)."""
    q = np.asarray(q, dtype=np.float64)
    m: np.ndarray = Rotation.from_quat(q.reshape(-1, 4), scalar_first=True).as_matrix()
    return m.reshape(*q.shape[:-1], 3, 3)


def make_sign_continuous(wxyz: np.ndarray) -> np.ndarray:
    """Flip quaternions (N, 4) so consecutive ones have a non-negative dot product (q and −q are equal).

    Returns a new array; the first quaternion keeps its sign.
    """
    q = np.array(wxyz, dtype=np.float64, copy=True)
    if len(q) < 2:
        return q
    flips = np.einsum("ij,ij->i", q[1:], q[:-1]) < 0
    sign = np.concatenate([[1.0], np.where(np.cumsum(flips) % 2 == 1, -1.0, 1.0)])
    return q * sign[:, None]


def quat_angle(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Rotation angle (rad) between quaternions ``a`` and ``b`` (…, 4), treating q and −q as equal.

    The inputs need not be normalised (see :func:`rotation_angle` for unit quaternions, without the norms).
    """
    d = np.abs(np.sum(np.asarray(a) * np.asarray(b), axis=-1))
    d = d / (np.linalg.norm(a, axis=-1) * np.linalg.norm(b, axis=-1))
    return 2.0 * np.arccos(np.clip(d, 0.0, 1.0))


def rotation_angle(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Rotation angle (rad) between unit quaternions a and b (…, 4); q and −q are the same orientation."""
    d = np.abs(np.einsum("...i,...i->...", a, b))
    return 2.0 * np.arccos(np.minimum(d, 1.0))


def relative_rotvec(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Rotation vectors (…, 3) of conj(a) ⊗ b for unit quaternions w, x, y, z (shortest rotation)."""
    aw, av = a[..., :1], a[..., 1:]
    bw, bv = b[..., :1], b[..., 1:]
    w = aw * bw + np.sum(av * bv, axis=-1, keepdims=True)
    v = aw * bv - bw * av - np.cross(av, bv)
    s = np.where(w < 0, -1.0, 1.0)
    w, v = w * s, v * s
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    ang = 2.0 * np.arctan2(n, w)
    out: np.ndarray = np.where(n > 1e-15, v * (ang / np.maximum(n, 1e-300)), 0.0)
    return out


def relative_axis(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Vector part of conj(a) ⊗ b with the sign that makes its scalar part ≥ 0, (N, 3).

    It points along the rotation vector of conj(a) ⊗ b (only its length differs), which is all an angle
    between two such vectors needs; cheaper than :func:`relative_rotvec` (no arctan, no cross product call).
    """
    aw, ax, ay, az = a[:, 0], a[:, 1], a[:, 2], a[:, 3]
    bw, bx, by, bz = b[:, 0], b[:, 1], b[:, 2], b[:, 3]
    w = aw * bw + ax * bx + ay * by + az * bz
    s = np.where(w < 0, -1.0, 1.0)
    vx = aw * bx - bw * ax - (ay * bz - az * by)
    vy = aw * by - bw * ay - (az * bx - ax * bz)
    vz = aw * bz - bw * az - (ax * by - ay * bx)
    return np.column_stack([vx * s, vy * s, vz * s])


def rotvec_matrix(r: np.ndarray) -> np.ndarray:
    """The rotation matrix (3, 3) of rotation vector ``r`` (3,) (axis × angle, rad)."""
    m: np.ndarray = Rotation.from_rotvec(np.asarray(r, dtype=np.float64)).as_matrix()
    return m


def slerp(q0: np.ndarray, q1: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Spherical interpolation (M, 4) w, x, y, z between unit quaternions at fractions ``s`` (M,) in [0, 1],
    the shortest way; the results keep the sign of ``q0``'s hemisphere."""
    ends = Rotation.from_quat(np.stack([q0, q1]), scalar_first=True)
    out: np.ndarray = Slerp([0.0, 1.0], ends)(np.clip(np.asarray(s, dtype=np.float64), 0.0, 1.0)).as_quat(
        scalar_first=True
    )
    return out * np.where(out @ np.asarray(q0, dtype=np.float64) < 0, -1.0, 1.0)[:, None]
