"""numpy on arrays of 3-vectors, in a fixed order of operations: the same bits on every CPU.

Building a scene (meshes, constraints' radii and spans, the base's surfaces) runs numpy on
whole arrays, and what it builds decides every frame after. numpy's elementwise ``+``,
``-``, ``*``, ``/`` and ``sqrt`` round each result as IEEE 754 requires, on any CPU. Its
``@``, ``dot``, ``einsum`` and ``linalg`` do not promise that: ``@`` and ``dot`` go to BLAS,
and ``linalg.eigh`` to LAPACK, whose kernels OpenBLAS chooses by the CPU it finds. A kernel
with fused multiply-adds rounds ``a*b + c`` once where one without rounds twice, and two
machines of the same kind (OpenBLAS's ``SkylakeX`` and ``Haswell`` kernels) gave a
cylinder different principal axes. So the simulation's modules compute with these, and
``tests/test_layers.py`` keeps ``@``, ``dot`` and ``linalg``'s BLAS calls out of them
(``tests/test_determinism.py`` replays the goldens under each kernel this CPU can run).
"""

from __future__ import annotations

import numpy as np

from . import spatial as sp


def dots(a, b) -> np.ndarray:
    """Row by row, the dot products of (..., 3) arrays, or of rows with one 3-vector:
    ``a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1] + a[..., 2] * b[..., 2]``, in that order."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1] + a[..., 2] * b[..., 2]


def norms(a) -> np.ndarray:
    """Row by row, the lengths of (..., 3) vectors (``sqrt(dots(a, a))``)."""
    return np.sqrt(dots(a, a))


def posed_points(points, pose: sp.Pose) -> np.ndarray:
    """``points`` (n, 3) moved by ``pose``: the rotation as a matrix (``sp.quat_to_matrix``),
    each new coordinate its row's three products summed in order, then the translation."""
    p = np.asarray(points, dtype=np.float64)
    (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = sp.quat_to_matrix(pose.rotation)
    x, y, z = p[:, 0], p[:, 1], p[:, 2]
    return np.column_stack([r00 * x + r01 * y + r02 * z + pose.position[0],
                            r10 * x + r11 * y + r12 * z + pose.position[1],
                            r20 * x + r21 * y + r22 * z + pose.position[2]])


def winding(vertices: np.ndarray, faces: np.ndarray, points: np.ndarray) -> np.ndarray:
    """The winding number of a closed mesh about each point: 1 inside, 0 outside (the solid
    angles of its triangles summed, Van Oosterom and Strackee's formula)."""
    out = np.zeros(len(points))
    tri = vertices[faces]
    for k in range(0, len(points), 64):  # (64 points x the triangles at a time)
        p = points[k:k + 64, None, :]
        a, b, c = tri[None, :, 0] - p, tri[None, :, 1] - p, tri[None, :, 2] - p
        la, lb, lc = norms(a), norms(b), norms(c)
        det = dots(a, np.cross(b, c))
        div = la * lb * lc + dots(a, b) * lc + dots(a, c) * lb + dots(b, c) * la
        out[k:k + 64] = np.arctan2(det, div).sum(axis=1) / (2.0 * np.pi)
    return out


def closed(faces: np.ndarray) -> bool:
    """Every edge of the mesh shared by exactly two of its triangles."""
    edges = np.sort(faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    return bool(len(counts)) and bool(np.all(counts == 2))
