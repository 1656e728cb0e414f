"""Assembly constraints between a part and the base part (paper 5.2, 5.3; NOTES.md).

A part declares in its session file the mates it makes with the base part, as in CAD:

- ``axis``: a shaft in a hole. A point and a direction on each; the part may slide along
  and turn about the base's axis (either can be switched off).
- ``plane``: a plane mate. A point and an outward normal on each; the part slides in the
  base's plane (a 2-vector) and keeps its orientation relative to the base.
- ``planes``: two plane mates at once; the part slides along their intersection line.

and its final assembled pose relative to the base. This module holds the frozen,
scene-time data of a mate (everything that does not change while it runs: the slide
directions and the shaft in base axes, the moment of inertia about the shaft, the feature
face sets the collision checks use) and the pure functions that recognise a mate at
release, snap the part onto it, and compose a part's pose from its coordinates.

The motion state of a constrained part is its coordinate relative to the base (``OnBase``
in ``state``): slide distance or in-plane 2-vector and the angle about the shaft, with
their rates. Its world pose is ``base pose * relative pose``, so a part that does not move
on the base rides with it exactly.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from typing import Final

import numpy as np

from . import spatial as sp
from .arrays import dots, norms

DEFAULT_DISTANCE_TOLERANCE_M = 0.005
DEFAULT_ANGLE_TOLERANCE_DEG = 10.0
DEFAULT_FINAL_DISTANCE_M = 0.002
DEFAULT_FINAL_ANGLE_DEG = 5.0


@dataclass(frozen=True, eq=False)
class Mate:
    """One recognisable constraint of a part with the base part; built once with the scene.

    Features are given on both sides: ``base_points``/``base_dirs`` in the base frame,
    ``part_points``/``part_dirs`` in the part frame (one pair for ``axis`` and ``plane``,
    two for ``planes``). Directions are unit vectors; for planes they are outward normals.
    """

    name: str
    kind: str
    base_points: tuple[sp.Vec3, ...]
    base_dirs: tuple[sp.Vec3, ...]
    part_points: tuple[sp.Vec3, ...]
    part_dirs: tuple[sp.Vec3, ...]
    radius: float                      # axis: radius of the shaft / bore (m); else 0
    distance_tolerance: float          # recognition (m)
    angle_tolerance: float             # recognition (rad)
    slide_dirs: tuple[sp.Vec3, ...]    # base frame, orthonormal; () when sliding is off
    turn: bool                         # axis: may turn about the base axis
    static_friction: float             # f_s
    dynamic_friction: float            # f_d
    rotational_friction: float         # f_r, N m s / rad: torque -f_r w
    holding_torque: float              # N m: static friction about the shaft (0: none)
    leave_when: str                    # plane: "center_of_mass_off" or "no_contact"
    inertia_about_axis: float          # J = u.I_cm u + m |r_perp|^2 (kg m^2), axis only
    cm_offset_part: sp.Vec3            # r_perp in the part frame: CM minus its foot on the axis
    sweep_radius: float                # farthest part vertex from the part axis (m)
    part_span: tuple[float, float]     # the whole part along the part axis, from its point
    part_feature_span: tuple[float, float]  # the bore (feature faces) along the part axis
    base_feature_span: tuple[float, float]  # the shaft (feature faces) along the base axis
    part_feature_faces: np.ndarray     # indices into the part's faces (read-only)
    base_feature_faces: np.ndarray     # indices into the base's faces (read-only)
    base_rest_faces: np.ndarray        # the base's other faces: what can block the part
    # axis: pairs of (part faces, faces of ``base_rest_faces``) that never meet: turning
    # and sliding keep every point's distance from the axis, and the part's faces lie
    # within a radius that the base's lie outside of, less the tolerance (a pin and its
    # bore's rim, a collar and its counterbore). Only base faces the part's come within the
    # tolerance of radially are listed (``physics.coaxial_fit`` radial; ``collision``).
    fit_groups: tuple = ()
    # axis: () where the part fits the shaft or bore; else (least, greatest) distance from
    # the axis of a face of it that does not, and the wall's distance (m): a part with no
    # face within the radius and one across the wall there (``radial_misfit``: a pin wider
    # than its bore, a disc with no bore), or a bore narrower than the shaft by more than
    # the tolerance (a sleeve). With ``coaxial_fit`` radial it is not put onto the
    # constraint when let go.
    misfit: tuple = ()

    # Derived once, on first use (a frozen dataclass without slots keeps these in its
    # __dict__; they are not fields, so they take no part in repr or construction).

    @cached_property
    def unit_axis(self) -> sp.Vec3:
        """``normalize(base_dirs[0])``: the shaft a part turns about, in base axes."""
        return sp.normalize(self.base_dirs[0])

    @cached_property
    def _axial_offsets(self) -> dict:
        """``axial_offset`` by snap pose: id -> (the pose itself, result)."""
        return {}


@dataclass(frozen=True, eq=False)
class Assembly:
    """A part's mates with the base and its final assembled pose (``base_from_part``)."""

    mates: tuple[Mate, ...]
    final_pose: sp.Pose | None
    final_distance: float              # m
    final_angle: float                 # rad


# --- building (scene time, numpy allowed) -----------------------------------------------

def _frozen_index(values) -> np.ndarray:
    out = np.asarray(values, dtype=np.int64).reshape(-1)
    out.setflags(write=False)
    return out


def _axis_distance(vertices: np.ndarray, point: sp.Vec3, direction: sp.Vec3) -> np.ndarray:
    rel = vertices - np.asarray(point)
    along = dots(rel, direction)
    perp = rel - np.outer(along, np.asarray(direction))
    return norms(perp)


# An edge between two corners at one distance from the axis, each on a ring (at least
# ``_RING`` corners of the mesh at that distance and one place along the axis), that turns
# through no more than this about the axis is a side of a cylinder or circle cut into a
# polygon (an 8-gon's or finer): with ``arcs``, its distance is its corners' (a 32-gon of
# 30 mm sags 0.14 mm). A flat face's edge beside the axis is not one: a ring of two.
_ARC_COS: Final = math.cos(math.pi / 8)
_RING: Final = 8
_RING_QUANTUM_M: Final = 1e-9


def radial_extent(vertices: np.ndarray, faces: np.ndarray, point: sp.Vec3,
                  direction: sp.Vec3, arcs: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Each face's least and greatest distance from an axis: of the triangle itself, not
    only its corners (a disc across the axis comes to 0; an annulus's inner edge, a chord,
    comes nearer than its corners). In the plane across the axis, the least is 0 where
    the triangle's shadow covers the axis, else the nearest of its three edges; with
    ``arcs``, an edge that is a side of a circle cut into a polygon (``_ARC_COS``) counts
    at its corners' distance: the circle it stands for, not the polygon's sag."""
    u = np.asarray(direction, dtype=np.float64)
    rel = np.asarray(vertices, dtype=np.float64) - np.asarray(point, dtype=np.float64)
    e1 = np.cross(u, (1.0, 0.0, 0.0) if abs(u[0]) < 0.9 else (0.0, 1.0, 0.0))
    e1 /= norms(e1)
    e2 = np.cross(u, e1)
    x, y = dots(rel, e1)[faces], dots(rel, e2)[faces]    # (n, 3): the shadow's corners
    most = np.sqrt((x * x + y * y).max(axis=1))
    # Edges a->b, b->c, c->a at once: the nearest point of each to the axis (the origin).
    x0, y0 = x, y
    x1, y1 = np.roll(x, -1, axis=1), np.roll(y, -1, axis=1)
    dx, dy = x1 - x0, y1 - y0
    length2 = dx * dx + dy * dy
    t = np.clip(-(x0 * dx + y0 * dy) / np.where(length2 > 0.0, length2, 1.0), 0.0, 1.0)
    px, py = x0 + t * dx, y0 + t * dy
    near = np.sqrt(px * px + py * py)
    if arcs and len(faces):
        # Each vertex's ring: its distance from the axis and place along it, to a quantum;
        # the corners of a face's edge on one ring of enough corners are an arc's.
        along = dots(rel, u)
        radius = np.sqrt(dots(rel, e1) ** 2 + dots(rel, e2) ** 2)
        level = np.round(radius / _RING_QUANTUM_M)
        # (One complex key a vertex: np.unique on a 1-D array, not on rows.)
        keys = level + 1j * np.round(along / _RING_QUANTUM_M)
        _, ring, size = np.unique(keys, return_inverse=True, return_counts=True)
        ring = np.asarray(ring).reshape(-1)
        on_ring = (size[ring] >= _RING)[faces]
        corner_level, r0 = level[faces], radius[faces]
        # (Both corners at one distance, each on a ring: a wall's diagonal joins two rings.)
        same = (corner_level == np.roll(corner_level, -1, axis=1)) & on_ring \
            & np.roll(on_ring, -1, axis=1) & (r0 > 0.0)
        # (A margin: an 8-gon's sides lie at _ARC_COS to the last bit, either side.)
        arc = same & (near >= _ARC_COS * (1.0 - 1e-9) * r0)
        near = np.where(arc, r0, near)
    least = near.min(axis=1)
    # Inside: the origin on the same side of all three edges (a triangle with area).
    side = x0 * dy - y0 * dx   # cross(edge, corner -> origin), up to sign
    area = dx[:, 0] * dy[:, 1] - dy[:, 0] * dx[:, 1]
    covers = (area != 0.0) & ((side >= 0.0).all(axis=1) | (side <= 0.0).all(axis=1))
    return np.where(covers, 0.0, least), most


def _bands(values: np.ndarray, tol: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``values`` in bands ``tol`` wide (cells from the least up): each value's band, and
    each band's least and greatest value."""
    if len(values) == 0:
        return np.zeros(0, dtype=np.int64), np.zeros(0), np.zeros(0)
    cells = np.floor((values - values.min()) / tol).astype(np.int64)
    _, band = np.unique(cells, return_inverse=True)
    band = np.asarray(band).reshape(-1)
    n = int(band.max()) + 1
    low, high = np.full(n, np.inf), np.full(n, -np.inf)
    np.minimum.at(low, band, values)
    np.maximum.at(high, band, values)
    return band, low, high


def _within(sorted_values: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """How many of ``sorted_values`` lie in each [lo, hi]."""
    return np.searchsorted(sorted_values, hi, side="right") \
        - np.searchsorted(sorted_values, lo, side="left")


def radial_fits(part_vertices: np.ndarray, part_faces: np.ndarray, part_point: sp.Vec3,
                part_axis: sp.Vec3, base_vertices: np.ndarray, base_faces: np.ndarray,
                base_point: sp.Vec3, base_axis: sp.Vec3, rest: np.ndarray,
                tol: float, part_extent: tuple[np.ndarray, np.ndarray] | None = None
                ) -> list[tuple[np.ndarray, np.ndarray]]:
    """The part faces and base faces of ``rest`` (indices into the part's and the base's
    faces) that a part on an axis constraint never meets, in groups.

    On the axis every point keeps its distance from it. A part face no farther from the
    axis than ``s`` and a base face no nearer than ``s - tol`` can overlap by at most the
    tolerance: a fit, not a collision (a pin in its bore passes the rim however tight,
    a nominal CAD fit included, as ``SKIP_COAXIAL`` already passes the bore's wall); so can
    a part face no nearer than ``s`` and a base face no farther than ``s + tol`` (a cup
    over a boss). The part's faces are taken in bands ``tol`` wide of their greatest and
    of their least distance; a band leaves out the base faces within the tolerance of it
    on the far side (those farther are farther than the tolerance anyway). Faces that
    leave out the same base faces are one group; none where nothing is left out."""
    least_p, most_p = part_extent if part_extent is not None \
        else radial_extent(part_vertices, part_faces, part_point, part_axis, True)
    least_b, most_b = radial_extent(base_vertices, base_faces[rest], base_point, base_axis,
                                    True)
    inner, _, tops = _bands(most_p, tol)
    outer, lows, _ = _bands(least_p, tol)
    # Inside: a band's top against base faces from it less the tolerance to it plus;
    # outside: its bottom against faces from it less to it plus the tolerance. (The reach,
    # a millionth over the tolerance: a face at the tolerance to the last bit is in.)
    reach = tol * (1.0 + 1e-6)
    near_in = _within(np.sort(least_b), tops - tol, tops + reach)
    near_out = _within(np.sort(most_b), lows - reach, lows + tol)
    if not near_in.any() and not near_out.any():
        return []  # nothing apart radially within the tolerance (most scenes): one query
    skip_in = [np.nonzero((least_b >= top - tol) & (least_b <= top + reach))[0] if n else
               np.zeros(0, dtype=np.int64) for top, n in zip(tops.tolist(), near_in.tolist())]
    skip_out = [np.nonzero((most_b <= low + tol) & (most_b >= low - reach))[0] if n else
                np.zeros(0, dtype=np.int64) for low, n in zip(lows.tolist(), near_out.tolist())]
    groups: dict[tuple[int, ...], list[np.ndarray]] = {}
    keys, which = np.unique(np.stack([inner, outer], axis=1), axis=0, return_inverse=True)
    which = np.asarray(which).reshape(-1)
    for k, (i, o) in enumerate(keys.tolist()):
        if not (near_in[i] or near_out[o]):
            continue
        skipped = np.union1d(skip_in[i], skip_out[o])
        if len(skipped):
            key = tuple(int(j) for j in rest[skipped])
            groups.setdefault(key, []).append(np.nonzero(which == k)[0])
    return [(np.sort(np.concatenate(faces)), np.array(key, dtype=np.int64))
            for key, faces in groups.items()]


def radial_misfit(part_vertices: np.ndarray, part_faces: np.ndarray, part_point: sp.Vec3,
                  part_axis: sp.Vec3, base_vertices: np.ndarray, wall_faces: np.ndarray,
                  base_point: sp.Vec3, base_axis: sp.Vec3, tol: float,
                  part_extent: tuple[np.ndarray, np.ndarray] | None = None
                  ) -> tuple[float, float, float] | None:
    """A part face lying across a wall of the shaft or bore, radially, by more than the
    tolerance: its least and greatest distance from the axis and the wall's; None if the
    part fits (every face within the wall's radius or outside it, to the tolerance, as the
    radial fits see them: ``radial_extent`` with arcs). A bottom or an end of the shaft is
    not a wall: a pin fits its blind bore."""
    if len(wall_faces) == 0 or len(part_faces) == 0:
        return None
    least_p, most_p = part_extent if part_extent is not None \
        else radial_extent(part_vertices, part_faces, part_point, part_axis, True)
    least_w, most_w = radial_extent(base_vertices, wall_faces, base_point, base_axis, True)
    # Across: most_p - tol > least_w and least_p + tol < most_w, for some pair. Walls by
    # their least distance, with the greatest of their greatest so far.
    order = np.argsort(least_w, kind="stable")
    least_w, most_w = least_w[order], most_w[order]
    running = np.maximum.accumulate(most_w)
    below = np.searchsorted(least_w, most_p - tol, side="left")
    crossing = (below > 0) & (running[np.maximum(below - 1, 0)] > least_p + tol)
    if not crossing.any():
        return None
    i = int(np.argmax(crossing))
    # The wall it crosses: the nearest one within its span.
    inside = np.nonzero((least_w < most_p[i] - tol) & (most_w > least_p[i] + tol))[0]
    return float(least_p[i]), float(most_p[i]), float(least_w[inside[0]])


def _faces_out(vertices: np.ndarray, faces: np.ndarray, point: sp.Vec3,
               direction: sp.Vec3) -> np.ndarray:
    """Whether each face's normal points away from an axis (a shaft's wall, a pin's side)
    rather than towards it (a bore's wall)."""
    tri = vertices[faces]
    normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    u = np.asarray(direction, dtype=np.float64)
    centre = tri.mean(axis=1) - np.asarray(point, dtype=np.float64)
    radial = centre - np.outer(dots(centre, u), u)
    return dots(normals, radial) > 0.0


def _along_axis(vertices: np.ndarray, faces: np.ndarray, direction: sp.Vec3) -> np.ndarray:
    """Whether each face lies along an axis, its normal square to it to a degree: a wall of
    a shaft or bore, not its end or bottom."""
    tri = vertices[faces]
    normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    lengths = norms(normals)
    along = np.abs(dots(normals, direction)) / np.where(lengths > 0.0, lengths, 1.0)
    return (lengths > 0.0) & (along <= math.sin(math.radians(1.0)))


def _walls_in(vertices: np.ndarray, faces: np.ndarray, point: sp.Vec3,
              direction: sp.Vec3) -> np.ndarray:
    """The faces (indices) along an axis that face it: a bore's walls."""
    if len(faces) == 0:
        return np.zeros(0, dtype=np.int64)
    return np.nonzero(_along_axis(vertices, faces, direction)
                      & ~_faces_out(vertices, faces, point, direction))[0]


def axis_feature_faces(vertices: np.ndarray, faces: np.ndarray, point: sp.Vec3,
                       direction: sp.Vec3, radius: float, tol: float) -> np.ndarray:
    """Faces lying within ``radius + tol`` of an axis: the shaft, or the wall of a bore."""
    radial = _axis_distance(vertices, point, direction)
    inside = radial <= radius + tol
    return np.nonzero(inside[faces].all(axis=1))[0]


def plane_feature_faces(vertices: np.ndarray, faces: np.ndarray, point: sp.Vec3,
                        normal: sp.Vec3, tol: float) -> np.ndarray:
    """Faces in a plane (within ``tol``) whose outward normal is the plane's normal."""
    height = np.abs(dots(vertices - np.asarray(point), normal))
    tri = vertices[faces]
    face_normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    lengths = norms(face_normals)
    lengths[lengths == 0.0] = 1.0
    facing = dots(face_normals, normal) / lengths > math.cos(math.radians(1.0))
    return np.nonzero((height[faces] <= tol).all(axis=1) & facing)[0]


def _span(vertices: np.ndarray, point: sp.Vec3, direction: sp.Vec3) -> tuple[float, float]:
    if len(vertices) == 0:
        return (0.0, 0.0)
    along = dots(vertices - np.asarray(point), direction)
    return (float(along.min()), float(along.max()))


def _orthonormal_pair(n: sp.Vec3) -> tuple[sp.Vec3, sp.Vec3]:
    """Two unit vectors spanning the plane normal to ``n`` (a fixed, documented choice)."""
    helper = (1.0, 0.0, 0.0) if abs(n[0]) < 0.9 else (0.0, 1.0, 0.0)
    e1 = sp.normalize(sp.cross(n, helper))
    return e1, sp.cross(n, e1)


def build_mate(*, name: str, kind: str, base_points, base_dirs, part_points, part_dirs,
               radius: float, distance_tolerance: float, angle_tolerance: float, slide: bool,
               turn: bool, static_friction: float, dynamic_friction: float,
               rotational_friction: float, holding_torque: float, leave_when: str, part_vertices: np.ndarray, part_faces: np.ndarray,
               mass_kg: float, center_of_mass: sp.Vec3, inertia_cm: sp.Mat3,
               base_vertices: np.ndarray, base_faces: np.ndarray, geometry_tol: float,
               coaxial_fit: str = "faces") -> Mate:
    """A ``Mate`` with every invariant computed once: J, spans, feature face sets. An axis's
    SKIP checks leave out the base's faces within the radius (the shaft, or the bore's
    wall); with ``coaxial_fit`` radial also what never meets the part (``radial_fits``)."""
    base_dirs = tuple(sp.normalize(d) for d in base_dirs)
    part_dirs = tuple(sp.normalize(d) for d in part_dirs)
    if kind == "axis":
        u_b, u_p = base_dirs[0], part_dirs[0]
        slide_dirs: tuple[sp.Vec3, ...] = (u_b,) if slide else ()
        part_feature = axis_feature_faces(part_vertices, part_faces, part_points[0], u_p,
                                          radius, geometry_tol)
        base_feature = axis_feature_faces(base_vertices, base_faces, base_points[0], u_b,
                                          radius, geometry_tol)
        rel = sp.sub(center_of_mass, part_points[0])
        r_perp = sp.sub(rel, sp.scale(u_p, sp.dot(rel, u_p)))
        # A CM on the axis to within a nanometre (a symmetric part, up to mesh round-off)
        # has no gravity torque: it does not turn by itself.
        if sp.norm(r_perp) < 1e-9:
            r_perp = sp.ZERO3
        inertia = sp.dot(u_p, sp.mat_vec(inertia_cm, u_p)) + mass_kg * sp.dot(r_perp, r_perp)
        sweep = float(_axis_distance(part_vertices, part_points[0], u_p).max())
        part_span = _span(part_vertices, part_points[0], u_p)
        part_feature_span = _span(part_vertices[np.unique(part_faces[part_feature])],
                                  part_points[0], u_p) if len(part_feature) else part_span
        base_feature_span = _span(base_vertices[np.unique(base_faces[base_feature])],
                                  base_points[0], u_b) if len(base_feature) else (0.0, 0.0)
    else:
        if kind == "plane":
            slide_dirs = _orthonormal_pair(base_dirs[0]) if slide else ()
        else:
            line = sp.cross(base_dirs[0], base_dirs[1])
            if sp.norm(line) < 1e-6:
                raise ValueError("the two planes are parallel: they do not define a line")
            slide_dirs = (sp.normalize(line),) if slide else ()
        turn = False
        part_feature = np.unique(np.concatenate([
            plane_feature_faces(part_vertices, part_faces, p, n, geometry_tol)
            for p, n in zip(part_points, part_dirs)]))
        base_feature = np.unique(np.concatenate([
            plane_feature_faces(base_vertices, base_faces, p, n, geometry_tol)
            for p, n in zip(base_points, base_dirs)]))
        r_perp, inertia, sweep = sp.ZERO3, 0.0, 0.0
        part_span = part_feature_span = base_feature_span = (0.0, 0.0)
    radial = kind == "axis" and coaxial_fit == "radial"
    skipped = base_feature
    misfit = None
    # The part's faces' distances from its axis, once, for the fits and the misfit.
    extent = radial_extent(part_vertices, part_faces, part_points[0], u_p, True) \
        if kind == "axis" else None
    if extent is not None and len(base_feature):
        # The shaft's or bore's walls, not its end or bottom; whether the part's faces
        # within the radius face out (a pin) or all face the axis (a sleeve's bore).
        walls = base_feature[_along_axis(base_vertices, base_faces[base_feature], u_b)]
        base_out = _faces_out(base_vertices, base_faces[walls], base_points[0], u_b)
        pin = bool(_faces_out(part_vertices, part_faces[part_feature], part_points[0],
                              u_p).any())
        if len(part_feature) == 0:
            # No bore (or pin) within the radius: a part with a face across the wall does
            # not go on (a pin wider than its bore, a disc with no bore); one clear of it
            # does (a sleeve's bore a little wider than the shaft's radius given, with a
            # cap or not: its bore's walls face the axis, no nearer than the shaft's).
            bore = _walls_in(part_vertices, part_faces, part_points[0], u_p)
            clear = bool(base_out.any()) and len(bore) > 0 \
                and float(extent[0][bore].min()) >= float(
                    radial_extent(base_vertices, base_faces[walls[base_out]],
                                  base_points[0], u_b, True)[1].max()) - geometry_tol
            if not clear:
                misfit = radial_misfit(part_vertices, part_faces, part_points[0], u_p,
                                       base_vertices, base_faces[walls], base_points[0],
                                       u_b, geometry_tol, extent)
        elif len(walls) and not pin:
            # A shaft (walls facing away from the axis) thicker than the part's bore (its
            # faces within the radius all facing the axis: a sleeve, not a pin) by more
            # than the tolerance: a sleeve narrower than its shaft.
            shaft = walls[base_out]
            if len(shaft):
                wall, _ = radial_extent(base_vertices, base_faces[shaft], base_points[0],
                                        u_b, True)
                low, high = extent[0][part_feature], extent[1][part_feature]
                r = float(wall.max())
                if float(high.max()) < r - geometry_tol:
                    k = int(np.argmax(high))
                    misfit = (float(low[k]), float(high[k]), r)
            else:
                # A bore (its walls facing the axis) and a part whose faces within the
                # radius are its own bore's: a hollow pin. Wider than the bore (a review:
                # a tube of 5.3 mm in 5) it does not fit, as a solid pin would not.
                misfit = radial_misfit(part_vertices, part_faces, part_points[0], u_p,
                                       base_vertices, base_faces[walls], base_points[0],
                                       u_b, geometry_tol, extent)
        if radial and pin:
            # A pin (faces within the radius facing out): only the bore's walls are left
            # out; a blind bore's bottom is checked, the radial fits leaving out what never
            # meets it. A sleeve keeps the shaft's end left out (a review: a hex sleeve,
            # whose flat bore is not taken for a circle, stuck on the shaft's end), and so
            # does a part with no face within the radius (a solid disc on a shaft).
            skipped = walls
    rest = np.setdiff1d(np.arange(len(base_faces)), skipped)
    fit_groups: list[tuple[np.ndarray, np.ndarray]] = []
    if radial and len(rest):
        fit_groups = radial_fits(part_vertices, part_faces, part_points[0], u_p,
                                 base_vertices, base_faces, base_points[0], u_b, rest,
                                 geometry_tol, extent)
    if kind != "axis":
        # SKIP_COPLANAR: base faces that lie wholly on or below a mating plane (the plate's
        # sides and bottom) can never be in the way of a part resting on top of it.
        below = np.zeros(len(base_vertices), dtype=bool)
        for p, n in zip(base_points, base_dirs):
            below |= dots(base_vertices - np.asarray(p), n) <= geometry_tol
        rest = rest[~below[base_faces[rest]].all(axis=1)]
    return Mate(
        name=name, kind=kind, base_points=tuple(base_points), base_dirs=base_dirs,
        part_points=tuple(part_points), part_dirs=part_dirs, radius=radius,
        distance_tolerance=distance_tolerance, angle_tolerance=angle_tolerance,
        slide_dirs=slide_dirs, turn=turn, static_friction=static_friction,
        dynamic_friction=dynamic_friction, rotational_friction=rotational_friction,
        holding_torque=holding_torque, leave_when=leave_when,
        inertia_about_axis=inertia, cm_offset_part=r_perp, sweep_radius=sweep,
        part_span=part_span, part_feature_span=part_feature_span,
        base_feature_span=base_feature_span, part_feature_faces=_frozen_index(part_feature),
        base_feature_faces=_frozen_index(base_feature), base_rest_faces=_frozen_index(rest),
        fit_groups=tuple((_frozen_index(a), _frozen_index(b)) for a, b in fit_groups),
        misfit=() if misfit is None else misfit)


# --- recognition and snapping (step time, plain floats) ---------------------------------

def _angle(a: sp.Vec3, b: sp.Vec3) -> float:
    """Angle between unit vectors, robust near 0 and pi."""
    return math.atan2(sp.norm(sp.cross(a, b)), sp.dot(a, b))


def _rotation_between(a: sp.Vec3, b: sp.Vec3) -> sp.Quat:
    """The smallest rotation taking unit vector a to unit vector b."""
    axis = sp.cross(a, b)
    s = sp.norm(axis)
    c = sp.dot(a, b)
    if s < 1e-12:
        if c > 0.0:
            return sp.IDENTITY_QUAT
        helper = (1.0, 0.0, 0.0) if abs(a[0]) < 0.9 else (0.0, 1.0, 0.0)
        return sp.quat_axis_angle(sp.cross(a, helper), math.pi)
    return sp.quat_axis_angle(axis, math.atan2(s, c))


def _triad(a: sp.Vec3, b: sp.Vec3) -> sp.Mat3:
    """Rows of an orthonormal frame built from two non-parallel vectors."""
    e1 = sp.normalize(a)
    e3 = sp.normalize(sp.cross(a, b))
    return (e1, sp.cross(e3, e1), e3)


def _posed(mate: Mate, base_from_part: sp.Pose) -> tuple[list[sp.Vec3], list[sp.Vec3]]:
    """The part's feature directions and points in base axes."""
    q = base_from_part.rotation
    return ([sp.quat_rotate(q, d) for d in mate.part_dirs],
            [base_from_part.apply(p) for p in mate.part_points])


def _along(d: sp.Vec3, u: sp.Vec3) -> sp.Vec3:
    """``d`` or its reverse, whichever points along ``u`` (an axis has no sense)."""
    return d if sp.dot(d, u) >= 0.0 else sp.scale(d, -1.0)


def _misalignment(mate: Mate, dirs: list[sp.Vec3], points: list[sp.Vec3]) -> tuple[float, float]:
    if mate.kind == "axis":
        u_b = mate.base_dirs[0]
        rel = sp.sub(points[0], mate.base_points[0])
        off = sp.sub(rel, sp.scale(u_b, sp.dot(rel, u_b)))
        return _angle(_along(dirs[0], u_b), u_b), sp.norm(off)
    angle = distance = 0.0
    for d, p, bp, bn in zip(dirs, points, mate.base_points, mate.base_dirs):
        angle = max(angle, _angle(d, sp.scale(bn, -1.0)))
        distance = max(distance, abs(sp.dot(sp.sub(p, bp), bn)))
    return angle, distance


def misalignment(mate: Mate, base_from_part: sp.Pose) -> tuple[float, float]:
    """How far the part's features are from the base's: ``(angle (rad), distance (m))``,
    the quantities ``recognise`` holds to the mate's tolerances (for two planes, the larger
    of the pair's). Why a release was not on the constraint, for a study."""
    return _misalignment(mate, *_posed(mate, base_from_part))


def recognise(mate: Mate, base_from_part: sp.Pose) -> sp.Pose | None:
    """The snapped ``base_from_part`` if the part's features are within tolerance, else None.

    Snapping removes the misalignment with the smallest rotation (about the part's own
    feature point) and the offset with the smallest translation, so the part keeps its
    position along the axis or in the plane and its angle about the axis.
    """
    dirs, points = _posed(mate, base_from_part)
    angle, distance = _misalignment(mate, dirs, points)
    if angle > mate.angle_tolerance or distance > mate.distance_tolerance:
        return None
    q = base_from_part.rotation
    if mate.kind == "axis":
        fix = _rotation_between(_along(dirs[0], mate.base_dirs[0]), mate.base_dirs[0])
    elif mate.kind == "plane":
        target = sp.scale(mate.base_dirs[0], -1.0)
        fix = _rotation_between(dirs[0], target)
    else:
        targets = [sp.scale(n, -1.0) for n in mate.base_dirs]
        # The rotation taking the part's normal pair onto the base's (reversed) pair.
        src, dst = _triad(dirs[0], dirs[1]), _triad(targets[0], targets[1])
        fix = sp.quat_from_matrix(sp.mat_mul(sp.transpose(dst), src))
    # Rotate about the (first) feature point, then push the point onto the base feature.
    pivot = points[0]
    rotation = sp.quat_normalize(sp.quat_mul(fix, q))
    position = sp.add(pivot, sp.quat_rotate(fix, sp.sub(base_from_part.position, pivot)))
    snapped = sp.Pose(position, rotation)
    if mate.kind == "axis":
        u_b = mate.base_dirs[0]
        rel = sp.sub(snapped.apply(mate.part_points[0]), mate.base_points[0])
        shift = sp.scale(sp.sub(rel, sp.scale(u_b, sp.dot(rel, u_b))), -1.0)
    else:
        shift = sp.ZERO3
        for _ in range(2):  # two planes: the second push does not undo the first
            for p, bp, bn in zip(mate.part_points, mate.base_points, mate.base_dirs):
                h = sp.dot(sp.sub(sp.add(snapped.apply(p), shift), bp), bn)
                shift = sp.sub(shift, sp.scale(bn, h))
    return sp.Pose(sp.add(snapped.position, shift), snapped.rotation)


def at_final_pose(assembly: Assembly, base_from_part: sp.Pose) -> bool:
    """Whether the part is at its final assembled pose within the stated tolerances."""
    final = assembly.final_pose
    if final is None:
        return False
    if sp.norm(sp.sub(base_from_part.position, final.position)) > assembly.final_distance:
        return False
    return sp.quat_angle_between(base_from_part.rotation, final.rotation) <= assembly.final_angle


def relative_pose(mate: Mate, base_from_snap: sp.Pose, slide: tuple[float, ...],
                  angle: float) -> sp.Pose:
    """``base_from_part`` at the given coordinates: slide, then turn about the base axis."""
    pose = base_from_snap
    if angle != 0.0:
        p = mate.base_points[0]
        turn = sp.quat_unit_axis_angle(mate.unit_axis, angle)
        position = sp.add(p, sp.quat_rotate(turn, sp.sub(pose.position, p)))
        pose = sp.Pose(position, sp.quat_normalize(sp.quat_mul(turn, pose.rotation)))
    if slide:
        shift = sp.ZERO3
        for x, e in zip(slide, mate.slide_dirs):
            shift = sp.add(shift, sp.scale(e, x))
        pose = sp.Pose(sp.add(pose.position, shift), pose.rotation)
    return pose


def cm_offset_base(mate: Mate, base_from_snap: sp.Pose) -> sp.Vec3:
    """r_perp in base axes at angle 0: from the shaft to the CM, normal to the shaft."""
    return sp.quat_rotate(base_from_snap.rotation, mate.cm_offset_part)


def axial_offset(mate: Mate, base_from_snap: sp.Pose) -> tuple[float, float]:
    """Where the part's own axis point sits on the base axis at slide 0, and the axis sign.

    A part keeps its snap pose (the same object) as long as it stays on the mate, and this
    is asked every frame: it is remembered per mate, keyed by the pose object's identity
    (the entry holds the pose, so the id cannot be reused while it is there). Exact: the
    same pose object gives the same result.
    """
    memo = mate._axial_offsets
    hit = memo.get(id(base_from_snap))
    if hit is not None and hit[0] is base_from_snap:
        return hit[1]
    if len(memo) >= 64:
        memo.clear()
    value = _axial_offset(mate, base_from_snap)
    memo[id(base_from_snap)] = (base_from_snap, value)
    return value


def _axial_offset(mate: Mate, base_from_snap: sp.Pose) -> tuple[float, float]:
    u_b = mate.base_dirs[0]
    c = sp.dot(sp.sub(base_from_snap.apply(mate.part_points[0]), mate.base_points[0]), u_b)
    sign = 1.0 if sp.dot(sp.quat_rotate(base_from_snap.rotation, mate.part_dirs[0]), u_b) >= 0 \
        else -1.0
    return c, sign
