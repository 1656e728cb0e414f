"""What holds a part up on a plane of the base: the region where its footprint meets the
plane's faces, and how far its centre of mass lies outside that region's convex hull.

``leave_when: center_of_mass_off`` used to say a part had slid off a plane once its centre
of mass was no longer above one of the plane's faces: over a hole or a slot in the face
(a CAD plate's bore, a slot narrower than the part) the part "slid off" though the face
held it on both sides, and flew into the plate (a CAD user's trial: a 40 mm block over a
12 mm slot rested 9 mm inside the plate). A rigid part on a plane is held up by the convex
hull of where it touches it: it tips once its centre of mass leaves that hull
(``CollisionWorld.support_gap``; ``step._still_on_base`` asks only where the centre of mass
is off the faces, so a plane without holes decides as before).

Plain numpy and a few lines of plane geometry: a 2-D convex hull (Andrew's monotone chain)
and the clip of a convex polygon by a triangle (Sutherland-Hodgman). scipy's ConvexHull
would do the first, but the commands keep scipy out of their imports (``scene``).
"""

from __future__ import annotations

import math

import numpy as np


def along(points: np.ndarray, direction) -> np.ndarray:
    """Each row of ``points`` (..., 3) dotted with ``direction``: three products summed in
    order, as ``arrays.posed_points`` does (no BLAS, whose sums differ between machines:
    ``tests/test_layers.py``)."""
    return (points[..., 0] * direction[0] + points[..., 1] * direction[1]
            + points[..., 2] * direction[2])


def plane_basis(normal) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors spanning the plane of ``normal`` (unit), orthogonal to each other."""
    n = [float(x) for x in normal]
    h = (1.0, 0.0, 0.0) if abs(n[0]) < 0.9 else (0.0, 1.0, 0.0)
    u = [n[1] * h[2] - n[2] * h[1], n[2] * h[0] - n[0] * h[2], n[0] * h[1] - n[1] * h[0]]
    length = math.sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2])
    u = [x / length for x in u]
    v = [n[1] * u[2] - n[2] * u[1], n[2] * u[0] - n[0] * u[2], n[0] * u[1] - n[1] * u[0]]
    return np.array(u), np.array(v)


def plane_triangles(vertices: np.ndarray, faces: np.ndarray, point, normal, tol: float,
                    basis: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """The triangles of ``faces`` that lie in the plane (every corner within ``tol`` of
    it), in the plane's 2-D coordinates (``basis``), each counter-clockwise: (n, 3, 2)."""
    if len(faces) == 0:
        return np.zeros((0, 3, 2))
    corners = np.asarray(vertices, dtype=np.float64)[np.asarray(faces)]  # (n, 3, 3)
    rel = corners - np.asarray(point, dtype=np.float64)
    flat = np.all(np.abs(along(rel, normal)) <= tol, axis=1)
    rel = rel[flat]
    tri = np.stack([along(rel, basis[0]), along(rel, basis[1])], axis=-1)  # (m, 3, 2)
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    area2 = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    tri = tri[area2 != 0.0]
    clockwise = area2[area2 != 0.0] < 0.0
    tri[clockwise] = tri[clockwise][:, ::-1]
    return tri


def convex_hull(points: np.ndarray) -> np.ndarray:
    """The convex hull of 2-D ``points`` (k, 2), counter-clockwise, without collinear
    points (Andrew's monotone chain); fewer than 3 rows where the points are collinear."""
    pts = np.unique(np.asarray(points, dtype=np.float64), axis=0)  # sorted by x, then y
    if len(pts) < 3:
        return pts

    def cross(o, a, b) -> float:
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])
    rows = [tuple(p) for p in pts]
    lower: list = []
    for p in rows:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], p) <= 0.0:
            lower.pop()
        lower.append(p)
    upper: list = []
    for p in reversed(rows):
        while len(upper) >= 2 and cross(upper[-2], upper[-1], p) <= 0.0:
            upper.pop()
        upper.append(p)
    return np.array(lower[:-1] + upper[:-1])


def _clip(polygon: list, a, b) -> list:
    """The part of convex ``polygon`` on the left of the directed line a -> b."""
    out = []
    n = len(polygon)
    for i in range(n):
        p, q = polygon[i], polygon[(i + 1) % n]
        sp_ = (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0])
        sq = (b[0] - a[0]) * (q[1] - a[1]) - (b[1] - a[1]) * (q[0] - a[0])
        if sp_ >= 0.0:
            out.append(p)
        if (sp_ >= 0.0) != (sq >= 0.0):
            t = sp_ / (sp_ - sq)
            out.append((p[0] + t * (q[0] - p[0]), p[1] + t * (q[1] - p[1])))
    return out


def _distance_outside(point, hull: np.ndarray) -> float:
    """How far 2-D ``point`` lies outside convex ``hull`` (counter-clockwise; 0 inside or on
    it); a hull of one or two points is that point or segment."""
    px, py = float(point[0]), float(point[1])
    n = len(hull)
    if n == 0:
        return math.inf
    if n >= 3:
        inside = True
        for i in range(n):
            (ax, ay), (bx, by) = hull[i], hull[(i + 1) % n]
            if (bx - ax) * (py - ay) - (by - ay) * (px - ax) < 0.0:
                inside = False
                break
        if inside:
            return 0.0
    best = math.inf
    for i in range(n if n >= 3 else max(n - 1, 1)):
        (ax, ay), (bx, by) = hull[i], hull[(i + 1) % n]
        dx, dy = bx - ax, by - ay
        length2 = dx * dx + dy * dy
        t = 0.0 if length2 == 0.0 else min(1.0, max(0.0, ((px - ax) * dx + (py - ay) * dy)
                                                      / length2))
        best = min(best, math.hypot(px - ax - t * dx, py - ay - t * dy))
    return best


def support_gap(foot, footprint: np.ndarray, triangles: np.ndarray) -> float:
    """How far ``foot`` (2-D: the centre of mass dropped onto the plane) lies outside the
    convex hull of where ``footprint`` (2-D points: the part's corners on the plane) meets
    ``triangles`` (``plane_triangles``): 0 inside, ``inf`` where they do not meet."""
    hull = convex_hull(footprint)
    if len(hull) < 3 or len(triangles) == 0:
        return math.inf  # an edge or a point on the plane: no area holds it up
    lo, hi = hull.min(axis=0), hull.max(axis=0)
    near = triangles[np.all(triangles.max(axis=1) >= lo, axis=1)
                     & np.all(triangles.min(axis=1) <= hi, axis=1)]
    held: list = []
    start = [tuple(p) for p in hull]
    for tri in near:
        piece = start
        for k in range(3):
            piece = _clip(piece, tri[k], tri[(k + 1) % 3])
            if not piece:
                break
        held.extend(piece)
    if not held:
        return math.inf
    return _distance_outside(foot, convex_hull(np.array(held)))
