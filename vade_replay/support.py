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

The corners of where the part's faces (or edges) in the plane meet the plane's faces are
the part's boundary corners inside the plane's faces, the plane's boundary corners inside
the part's faces (each asked of fcl, a point's distance to a BVH), and where the two
boundaries cross (``crossings``, numpy): their hull is the region's. A review of the first
version, which clipped the hull of the part's corners by every face of the plane, found a
U-shaped part held by a rib under its notch, 0.5 s an evaluation on a CAD plate of 100k
faces, and a rod on a line of its facets dropped into a slot it spans.

Plain numpy and a few lines of plane geometry: a 2-D convex hull (Andrew's monotone chain)
and segment crossings. scipy's ConvexHull would do the first, but the commands keep scipy
out of their imports (``scene``).
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


def in_plane(vertices: np.ndarray, faces: np.ndarray, point, normal, tol: float) -> np.ndarray:
    """Which of ``faces`` lie in the plane: every corner within ``tol`` of it (a mask)."""
    near = np.abs(along(np.asarray(vertices, dtype=np.float64)
                        - np.asarray(point, dtype=np.float64), normal)) <= tol
    return np.all(near[np.asarray(faces, dtype=np.int64)], axis=1)


def plane_edges(vertices: np.ndarray, faces: np.ndarray, point, normal,
                tol: float) -> np.ndarray:
    """The edges (vertex index pairs, (n, 2)) that bound what of a mesh lies in the plane:
    the boundary of its faces in the plane (every corner within ``tol`` of it; an edge one
    such face has), and its edges in the plane that no such face has (a rod lying on a
    line of its facets). The edges inside the faces in the plane are left out: a point of
    where two regions meet that is a corner of it lies on the boundary of each, or is a
    corner of one inside the other."""
    faces = np.asarray(faces, dtype=np.int64)
    if len(faces) == 0:
        return np.zeros((0, 2), dtype=np.int64)
    near = np.abs(along(np.asarray(vertices, dtype=np.float64)
                        - np.asarray(point, dtype=np.float64), normal)) <= tol
    flat = np.all(near[faces], axis=1)  # (``in_plane``, with ``near`` kept for the edges)
    edges = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]),
                    axis=1)
    in_flat = np.concatenate([flat, flat, flat])
    lying = np.all(near[edges], axis=1)
    kept, counts = np.unique(edges[in_flat], axis=0, return_counts=True)
    inner = kept[counts >= 2]
    candidates = np.unique(edges[lying], axis=0)
    if len(inner) == 0:
        return candidates
    # Those of ``candidates`` not among ``inner``: rows compared as one integer each.
    scale = int(max(candidates.max(), inner.max())) + 1
    drop = np.isin(candidates[:, 0] * scale + candidates[:, 1], inner[:, 0] * scale + inner[:, 1])
    return candidates[~drop]


def crossings(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Where the 2-D segments ``a`` (n, 2, 2) cross the segments ``b`` (m, 2, 2): (k, 2)."""
    if len(a) == 0 or len(b) == 0:
        return np.zeros((0, 2))
    a_lo, a_hi = a.min(axis=1), a.max(axis=1)
    b_lo, b_hi = b.min(axis=1), b.max(axis=1)
    i, j = np.nonzero(np.all(a_lo[:, None, :] <= b_hi[None, :, :], axis=2)
                      & np.all(b_lo[None, :, :] <= a_hi[:, None, :], axis=2))
    if len(i) == 0:
        return np.zeros((0, 2))
    p, r = a[i, 0], a[i, 1] - a[i, 0]
    q, s = b[j, 0], b[j, 1] - b[j, 0]
    denom = r[:, 0] * s[:, 1] - r[:, 1] * s[:, 0]
    qp = q - p
    ok = denom != 0.0
    safe = np.where(ok, denom, 1.0)
    t = (qp[:, 0] * s[:, 1] - qp[:, 1] * s[:, 0]) / safe
    u = (qp[:, 0] * r[:, 1] - qp[:, 1] * r[:, 0]) / safe
    hit = ok & (t >= 0.0) & (t <= 1.0) & (u >= 0.0) & (u <= 1.0)
    return p[hit] + t[hit, None] * r[hit]


def convex_hull(points: np.ndarray) -> np.ndarray:
    """The convex hull of 2-D ``points`` (k, 2), counter-clockwise, without collinear
    points (Andrew's monotone chain); fewer than 3 rows where the points are collinear."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    if len(pts) == 0:
        return pts
    pts = pts[np.lexsort((pts[:, 1], pts[:, 0]))]  # by x, then y
    keep = np.ones(len(pts), dtype=bool)
    keep[1:] = np.any(pts[1:] != pts[:-1], axis=1)  # (np.unique on rows is ~10x slower)
    pts = pts[keep]
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


def distance_outside(point, hull: np.ndarray) -> float:
    """How far 2-D ``point`` lies outside convex ``hull`` (counter-clockwise; 0 inside or on
    it); a hull of one or two points is that point or segment."""
    return nearest_in_hull(point, hull)[0]


def nearest_in_hull(point, hull: np.ndarray) -> tuple[float, float, float]:
    """``distance_outside`` and the point of ``hull`` nearest 2-D ``point`` (``point``
    itself inside or on it): (distance, x, y); (inf, x, y) of ``point`` for no hull."""
    px, py = float(point[0]), float(point[1])
    n = len(hull)
    if n == 0:
        return math.inf, px, py
    if n >= 3:
        inside = True
        for i in range(n):
            (ax, ay), (bx, by) = hull[i], hull[(i + 1) % n]
            if (bx - ax) * (py - ay) - (by - ay) * (px - ax) < 0.0:
                inside = False
                break
        if inside:
            return 0.0, px, py
    best, qx, qy = math.inf, px, py
    for i in range(n if n >= 3 else max(n - 1, 1)):
        (ax, ay), (bx, by) = hull[i], hull[(i + 1) % n]
        dx, dy = bx - ax, by - ay
        length2 = dx * dx + dy * dy
        t = 0.0 if length2 == 0.0 else min(1.0, max(0.0, ((px - ax) * dx + (py - ay) * dy)
                                                      / length2))
        h = math.hypot(px - ax - t * dx, py - ay - t * dy)
        if h < best:
            best, qx, qy = h, float(ax + t * dx), float(ay + t * dy)
    return best, qx, qy


def distance_to_pieces(point, triangles: np.ndarray, segments: np.ndarray) -> float:
    """How far 2-D ``point`` is from the nearest of ``triangles`` (k, 3, 2) and ``segments``
    (j, 2, 2): 0 inside or on a triangle, ``inf`` where there are none. A triangle of no
    area (its corners in a line) is its edges: the signs of its sides tell nothing."""
    p = np.asarray(point, dtype=np.float64)
    best = math.inf
    if len(triangles):
        a, b, c = triangles[:, 0], triangles[:, 1], triangles[:, 2]

        def side(u: np.ndarray, v: np.ndarray) -> np.ndarray:
            return ((v[:, 0] - u[:, 0]) * (p[1] - u[:, 1])
                    - (v[:, 1] - u[:, 1]) * (p[0] - u[:, 0]))
        s1, s2, s3 = side(a, b), side(b, c), side(c, a)
        area = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
        inside = ((s1 >= 0) & (s2 >= 0) & (s3 >= 0)) | ((s1 <= 0) & (s2 <= 0) & (s3 <= 0))
        if np.any(inside & (area != 0.0)):
            return 0.0
        segments = np.concatenate([segments.reshape(-1, 2, 2), np.stack([a, b], axis=1),
                                   np.stack([b, c], axis=1), np.stack([c, a], axis=1)])
    if len(segments):
        u, v = segments[:, 0], segments[:, 1]
        d = v - u
        length2 = d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1]
        t = np.where(length2 > 0.0, ((p[0] - u[:, 0]) * d[:, 0] + (p[1] - u[:, 1]) * d[:, 1])
                     / np.where(length2 > 0.0, length2, 1.0), 0.0)
        t = np.clip(t, 0.0, 1.0)
        best = float(np.min(np.hypot(p[0] - u[:, 0] - t * d[:, 0], p[1] - u[:, 1] - t * d[:, 1])))
    return best


def support_gap(foot, held: np.ndarray) -> float:
    """How far ``foot`` (2-D: the centre of mass dropped onto the plane) lies outside the
    convex hull of ``held`` (2-D points of where the part meets the plane's faces, its
    corners among them): 0 inside or on it, ``inf`` where there are none. A hull of two
    points is a segment of contact (a rod on a line of its facets), held on it."""
    if len(held) == 0:
        return math.inf
    return distance_outside(foot, convex_hull(held))
