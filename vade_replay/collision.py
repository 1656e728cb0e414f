"""Collision queries with python-fcl; the only module that imports fcl.

``CollisionWorld`` builds every BVH once from the Scene, including, per constraint of a
part with the base (``constraints.Mate``), the feature sub-meshes of paper section 6.
Checks against the base run in base axes, so the base itself never moves in them:

- ``KEEP_COPLANAR``: the part's feature faces against the base's feature faces (the
  touching parallel faces, or the bore on the shaft): is the part still on the base?
- ``SKIP_COPLANAR``: the whole part, lifted off the plane by twice the contact tolerance,
  against the base without its feature faces: is anything else of the base in the way?
- ``SKIP_COAXIAL`` (``SKIP_CYLINDER``): the whole part against the base without the faces
  inside the shaft's radius (an equal-diameter coaxial fit is not a collision).
- ``NOCARE_COPLANAR``: the plain check, whole part against whole base.

A query first runs a cheap bounding test (a sphere around the part's centre of mass against
each object's world box) and asks fcl only for the objects that can touch. "Still within
the tolerance of the base?" is first asked of the pair of triangles that last was
(``base_distance_within``: a witness pair, kept as one-triangle BVHs built when found); only
its yes is taken. ``stats`` counts what was asked (fcl queries, bounding tests, witness
tests), for the replay summary; it is instrumentation and never feeds back into the
simulation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Enum
from typing import Final

import fcl
import numpy as np

from . import spatial as sp
from . import support
from .arrays import closed, dots, norms, posed_points, winding
from .constraints import Mate, radial_extent
from .scene import Body, Scene


class CheckMode(str, Enum):
    """The coplanar and coaxial options of paper section 6."""

    KEEP_COPLANAR = "KEEP_COPLANAR"
    SKIP_COPLANAR = "SKIP_COPLANAR"
    SKIP_COAXIAL = "SKIP_COAXIAL"
    SKIP_CYLINDER = "SKIP_COAXIAL"  # the paper's other name for the same check
    NOCARE_COPLANAR = "NOCARE_COPLANAR"


# Read once: compiled, ``CheckMode.X`` is a lookup through ``EnumType.__getattr__``
# (~700 instructions); a Final name is a C static (``step`` does the same for the modes).
KEEP_COPLANAR: Final = CheckMode.KEEP_COPLANAR
SKIP_COPLANAR: Final = CheckMode.SKIP_COPLANAR
SKIP_COAXIAL: Final = CheckMode.SKIP_COAXIAL
NOCARE_COPLANAR: Final = CheckMode.NOCARE_COPLANAR


def _bvh_of(vertices: np.ndarray, faces: np.ndarray) -> fcl.BVHModel | None:
    if len(faces) == 0:
        return None
    used, local = np.unique(faces, return_inverse=True)
    model = fcl.BVHModel()
    model.beginModel(len(used), len(faces))
    model.addSubModel(np.ascontiguousarray(vertices[used], dtype=np.float64),
                      np.ascontiguousarray(local.reshape(-1, 3), dtype=np.int64))
    model.endModel()
    return model


def _bvh(body: Body) -> fcl.BVHModel:
    return _bvh_of(body.vertices, body.faces)


def _distance(a: fcl.CollisionObject, b: fcl.CollisionObject) -> float:
    return fcl.distance(a, b, fcl.DistanceRequest(), fcl.DistanceResult())


class _MateGeometry:
    """BVHs of one constraint: the two feature sub-meshes and the rest, with the triangles
    of each (what fcl's primitive indices count). The rest's is built with it; the feature
    sub-meshes' (``KEEP_COPLANAR``, ``support_distance``) the first time they are asked for:
    a part that only turns on its shaft, or slides and never nears its end, never pays for
    them (the same models whenever built)."""

    def __init__(self, part_vertices: np.ndarray, base_vertices: np.ndarray,
                 base_rest: fcl.CollisionObject | None, sweep: fcl.Cylinder | None,
                 sweep_center: float, part_feature_faces: np.ndarray,
                 base_feature_faces: np.ndarray, base_rest_faces: np.ndarray,
                 fit_pairs: tuple | None) -> None:
        self._part_vertices = part_vertices
        self._base_vertices = base_vertices
        self.base_rest = base_rest
        self.sweep = sweep                      # the part's solid of revolution about its axis
        self.sweep_center = sweep_center        # middle of the part's span along its axis
        self.part_feature_faces = part_feature_faces
        self.base_feature_faces = base_feature_faces
        self.base_rest_faces = base_rest_faces
        # SKIP_COAXIAL with ``physics.coaxial_fit`` radial where the part has fits
        # (``Mate.fit_groups``): the part's model (None: the whole part's) and the base's
        # object of each query, and their triangles; their least distance is the part's.
        # None: the whole part against the rest, one query.
        self.fit_pairs = fit_pairs
        self._features_built = False
        self._part_feature: fcl.BVHModel | None = None
        self._base_feature: fcl.CollisionObject | None = None

    def _features(self) -> None:
        if not self._features_built:
            self._part_feature = _bvh_of(self._part_vertices, self.part_feature_faces)
            model = _bvh_of(self._base_vertices, self.base_feature_faces)
            self._base_feature = None if model is None else fcl.CollisionObject(
                model, fcl.Transform())
            self._features_built = True

    def part_feature(self) -> fcl.BVHModel | None:
        """The part's feature faces' model (None where it has none)."""
        self._features()
        return self._part_feature

    def base_feature(self) -> fcl.CollisionObject | None:
        """The base's feature faces' object (None where it has none)."""
        self._features()
        return self._base_feature


@dataclass(eq=False)
class _Surface:
    """Faces of the base joined at folds under ``_FOLD_DEG`` (``base_surfaces``), their box
    (base axes), and their BVH once asked for."""

    faces: np.ndarray
    lo: sp.Vec3
    hi: sp.Vec3
    obj: fcl.CollisionObject | None = None
    # Its outward normal (base axes) and its plane's offset along it if it is flat, None if
    # curved; asked for once (``CollisionWorld.flat_plane``).
    flat: tuple[sp.Vec3, float] | None = None
    flat_known: bool = False


@dataclass(eq=False)
class _SupportDetail:
    """What ``CollisionWorld.support_gap`` asks where a plane's outline does not settle it:
    the plane's faces' boundary (2-D segments) and corners (3-D, base axes), the part's
    boundary (or line) in its own plane (3-D segments, part frame), and the part's faces
    there (a BVH's object, or None)."""

    boundary: np.ndarray
    corners: np.ndarray
    part_edges: np.ndarray
    part_flat: fcl.CollisionObject | None


@dataclass(eq=False)
class _SupportPlane:
    """A plane mate's plane as ``CollisionWorld.support_gap`` asks it: its point, unit
    normal and 2-D axes, the hull of its faces' corners (2-D), and the rest once needed."""

    point: np.ndarray
    normal: np.ndarray
    basis: tuple[np.ndarray, np.ndarray]
    outline: np.ndarray
    detail: _SupportDetail | None = None

    def flat2(self, points: np.ndarray) -> np.ndarray:
        """Points (n, 3), base axes, in the plane's 2-D coordinates."""
        return _flat2(points, self.point, self.basis)


def _flat2(points: np.ndarray, point: np.ndarray,
           basis: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    rel = points - point
    return np.stack([support.along(rel, basis[0]), support.along(rel, basis[1])], axis=-1)


# A centre of mass no farther than this (m) outside the hull of the part's footprint on a
# plane is over it (``CollisionWorld.stand_in``: round-off put a rod's 4e-18 m off its line).
_OVERHANG_MIN_M: Final = 1e-9
# ``passed_distance``: passing faces alike to this (m) in radial extent and middle along the
# axis are one candidate; at most this many candidates are tried for a place beside the part.
_RING_KEY_M: Final = 1e-9
_PASSED_TRIES: Final = 16


@dataclass(eq=False)
class AxialSplit:
    """The base faces of a ``SKIP_COAXIAL`` check split for a part moved along its axis
    constraint's base axis from one pose (``CollisionWorld.axial_split``). Such a move keeps
    every point's distance from the axis, so a base face lying radially apart from the
    part's faces, by its least and greatest distance from the axis against theirs
    (``radial_extent``), is never met, nor nearer than that radial gap. Per query of the
    check (the whole part against the rest, or each radial fit's pair): ``blocking``, the
    part's model (None: the whole part's) and the base faces not apart (None where there
    are none); ``passing``, those apart by under ``near`` (``_Passing``). ``far_gap``: the
    least radial gap of the other faces apart (inf: none). ``empty``: the check compares
    nothing (``base_distance`` is inf)."""

    blocking: list
    passing: list
    far_gap: float
    empty: bool


@dataclass(eq=False)
class _Passing:
    """Base faces of one query apart radially from the part by under ``near``: the part's
    model (None: the whole part's) and their object; per face its radial gap, its least,
    greatest and middle place along the axis, and its least and greatest distance from it;
    per part face of the query (posed) its least and greatest place along the axis and
    distance from it."""

    model: fcl.BVHModel | None
    obj: fcl.CollisionObject | None
    gap: np.ndarray
    z_lo: np.ndarray
    z_hi: np.ndarray
    z_mid: np.ndarray
    r_lo: np.ndarray
    r_hi: np.ndarray
    part_z_lo: np.ndarray
    part_z_hi: np.ndarray
    part_r_lo: np.ndarray
    part_r_hi: np.ndarray


# Faces meeting at a fold under this are one surface (a plane meshed finely, a cylinder's
# side); the base's edges and corners are sharper.
_FOLD_DEG = 30.0
_FACE_COS = math.cos(math.radians(30.0))
# A surface whose faces' normals are all within this of their mean is flat (a plane meshed
# in triangles: their normals agree to round-off).
_FLAT_COS = math.cos(math.radians(0.5))


def base_surfaces(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """A label per face, the least face index of its surface: faces reached from that face
    across edges folded under ``_FOLD_DEG`` whose normals stay within ``_FOLD_DEG`` of its
    own. A flat stretch of a mesh, however finely cut, is one surface; a box's six faces
    are six; a cylinder's side is a few, each turning at most that much (a review: folds
    alone joined a wall, a finely cut fillet and the plate below into one surface, which a
    part leaving the wall then passed through)."""
    n = len(faces)
    labels = np.full(n, -1, dtype=np.int64)
    if n == 0:
        return labels
    tri = vertices[faces]
    normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    lengths = norms(normals)
    normals = normals / np.where(lengths > 0.0, lengths, 1.0)[:, None]
    edges = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]),
                    axis=1)
    owner = np.tile(np.arange(n), 3)
    order = np.lexsort((edges[:, 1], edges[:, 0]))
    edges, owner = edges[order], owner[order]
    same = np.all(edges[1:] == edges[:-1], axis=1)
    a, b = owner[:-1][same], owner[1:][same]
    limit = math.cos(math.radians(_FOLD_DEG))
    smooth = dots(normals[a], normals[b]) >= limit
    a, b = np.concatenate([a[smooth], b[smooth]]), np.concatenate([b[smooth], a[smooth]])
    by = np.lexsort((b, a))
    a, b = a[by], b[by]
    starts = np.searchsorted(a, np.arange(n + 1))
    neighbours, unit = b.tolist(), normals.tolist()
    bounds = starts.tolist()
    out = labels.tolist()
    for seed in range(n):
        if out[seed] >= 0:
            continue
        out[seed] = seed
        sx, sy, sz = unit[seed]
        stack = [seed]
        while stack:
            face = stack.pop()
            for k in range(bounds[face], bounds[face + 1]):
                other = neighbours[k]
                if out[other] < 0:
                    ox, oy, oz = unit[other]
                    if sx * ox + sy * oy + sz * oz >= limit:
                        out[other] = seed
                        stack.append(other)
    return np.array(out, dtype=np.int64)


# A witness pair decides "within the tolerance" only this far inside it: far above the
# round-off of one triangle distance (fcl computes the pair's distance the same way inside
# the whole query), far below anything physical.
_WITNESS_MARGIN_M = 1e-12
_WITNESS_PAIRS = True  # the shortcut of base_distance_within (off in a test)


def _transform(pose: sp.Pose) -> fcl.Transform:
    x, y, z, w = pose.rotation
    return fcl.Transform(np.array([w, x, y, z]), np.array(pose.position, dtype=np.float64))


@dataclass(frozen=True)
class _Fixed:
    name: str
    obj: fcl.CollisionObject
    lo: sp.Vec3
    hi: sp.Vec3
    body: Body


class CollisionWorld:
    """Collision geometry of a Scene, built once."""

    def __init__(self, scene: Scene) -> None:
        # A part's BVH is built the first time it is queried: parts that only ever rest on
        # the table never pay for one.
        self._bodies = {body.name: body for body in scene.parts}
        self._part_models: dict[str, fcl.BVHModel] = {}
        self._fixed: list[_Fixed] = []
        self._solid: dict[int, bool] = {}  # (``inside_environment``)
        for body in scene.environment:
            pose = body.initial_pose
            world = np.array([pose.apply(tuple(v)) for v in body.vertices])
            obj = fcl.CollisionObject(_bvh(body), _transform(pose))
            self._fixed.append(_Fixed(body.name, obj, tuple(world.min(axis=0)),
                                      tuple(world.max(axis=0)), body))
        # The base's BVH and each constraint's (``_mate``) are built the first time they are
        # asked for too: a constraint no part comes near in a session costs nothing, nor
        # does the base of a session whose parts never meet it. (The same models as built
        # up front: a query's answer does not depend on when its BVH was made.)
        self._base = scene.base
        self._radial = scene.physics.coaxial_fit == "radial"
        self._identity = fcl.Transform()
        self._whole_obj: fcl.CollisionObject | None = None
        self._mates: dict[tuple[str, int], _MateGeometry] = {}
        self._base_faces = self._base_vertices = np.zeros((0, 3))
        self.base_radius = 0.0  # farthest base vertex from the base frame's origin
        if scene.base is not None:
            base = scene.base
            self._base_faces, self._base_vertices = base.faces, base.vertices
            self.base_radius = float(np.max(norms(base.vertices)))
        # The base's surfaces (``base_surfaces``), made when a part first leaves the base:
        # a flight passes those it touched as it left until the two have separated once.
        self._base_surfaces: list[_Surface] | None = None
        # Per (part, constraint, surface): the surface's faces its SKIP checks keep.
        self._rest_surfaces: dict[tuple[str, int, int], fcl.CollisionObject | None] = {}
        self._probe = fcl.Sphere(1e-9)
        # Per (part, constraint, plane): what ``support_gap`` asks of it (``_SupportPlane``),
        # made the first time a centre of mass is off the plane's faces.
        self._support_planes: dict[tuple[str, int, int], _SupportPlane] = {}
        # Per (part, constraint, plane): what stands for the centre of mass there, and
        # whether the part's own faces cover it (``stand_in``).
        self._stand_ins: dict[tuple[str, int, int], tuple[sp.Vec3 | None, bool]] = {}
        # Per (part, constraint, query): the base faces' radial extents and axial middles
        # (``axial_split``), and per faces of a split their object.
        self._axial_extents: dict[tuple[str, int, int], tuple[np.ndarray, np.ndarray,
                                                              np.ndarray, np.ndarray,
                                                              np.ndarray]] = {}
        self._split_objects: dict[tuple[str, int, int, str, bytes],
                                  fcl.CollisionObject | None] = {}
        # Per (part, mate, mode): the pair of triangles that last came within the tolerance
        # (``base_distance_within``), as one-triangle BVHs.
        self._witnesses: dict[tuple[str, int, CheckMode],
                              tuple[fcl.BVHModel, fcl.CollisionObject]] = {}
        # The run's counters (instrumentation: they never change a result). The step adds
        # its integrator sub-steps and closed-form evaluations here too.
        self.stats = {"bounding_tests": 0, "fcl_distance_queries": 0, "witness_tests": 0,
                      "integrator_steps": 0, "closed_form_evals": 0}

    def _model(self, part: str) -> fcl.BVHModel:
        model = self._part_models.get(part)
        if model is None:
            model = self._part_models[part] = _bvh(self._bodies[part])
        return model

    def _whole(self) -> fcl.CollisionObject:
        """The whole base's object (a scene with a base only)."""
        whole = self._whole_obj
        if whole is None:
            assert self._base is not None
            whole = self._whole_obj = fcl.CollisionObject(_bvh(self._base), self._identity)
        return whole

    def _mate(self, part: str, mate: int) -> _MateGeometry:
        """A part's constraint's BVHs (``_MateGeometry``), built the first time."""
        geometry = self._mates.get((part, mate))
        if geometry is None:
            body, base = self._bodies[part], self._base
            if base is None or body.assembly is None or not 0 <= mate < len(body.assembly.mates):
                raise KeyError((part, mate))
            geometry = self._mates[(part, mate)] = self._mate_geometry(
                body, base, body.assembly.mates[mate], self._identity, self._radial)
        return geometry

    @staticmethod
    def _mate_geometry(body: Body, base: Body, mate: Mate, identity,
                       radial: bool) -> _MateGeometry:
        def obj(model):
            return None if model is None else fcl.CollisionObject(model, identity)
        sweep = None
        if mate.turn:
            lo, hi = mate.part_span
            sweep = fcl.Cylinder(mate.sweep_radius, max(hi - lo, 1e-9))
        part_feature = body.faces[mate.part_feature_faces]
        base_feature = base.faces[mate.base_feature_faces]
        base_rest = base.faces[mate.base_rest_faces]
        rest_obj = obj(_bvh_of(base.vertices, base_rest))
        pairs: tuple | None = None
        if radial and mate.fit_groups:
            # The least distance of each group of the part's faces to the rest less what
            # that group never meets, as: the whole part against the rest less all that any
            # group never meets (one BVH, the base's bulk), each group against what the
            # others never meet and it does, and the faces in no group against all of that
            # (small BVHs: rims). A model of None is the part's own (``_model``).
            queries: list = []
            skipped_any = np.unique(np.concatenate([k for _, k in mate.fit_groups]))
            bulk = base.faces[np.setdiff1d(mate.base_rest_faces, skipped_any)]
            grouped = np.concatenate([faces for faces, _ in mate.fit_groups])
            ungrouped = np.setdiff1d(np.arange(len(body.faces)), grouped)
            rest_of_it: list = [(None, bulk)]
            rest_of_it += [(faces, base.faces[np.setdiff1d(skipped_any, skipped)])
                           for faces, skipped in [(ungrouped, np.zeros(0, dtype=np.int64)),
                                                  *mate.fit_groups]]
            # Each query's radial gap, a lower bound of its distance: the part's faces all
            # nearer the axis than the base's, or all farther (a group's part faces far out
            # from a shaft's end, say), to skip it where the nearer queries already found
            # less (the bulk is first).
            lo_p, hi_p = radial_extent(body.vertices, body.faces, mate.part_points[0],
                                       mate.part_dirs[0])
            for faces, kept in rest_of_it:
                other = obj(_bvh_of(base.vertices, kept))
                if other is None:
                    continue
                lo_b, hi_b = radial_extent(base.vertices, kept, mate.base_points[0],
                                           mate.base_dirs[0])
                if faces is None:
                    queries.append((None, other, body.faces, kept, 0.0))
                elif len(faces):
                    model = _bvh_of(body.vertices, body.faces[faces])
                    gap = max(0.0, float(lo_b.min()) - float(hi_p[faces].max()),
                              float(lo_p[faces].min()) - float(hi_b.max()))
                    queries.append((model, other, body.faces[faces], kept, gap))
            pairs = tuple(queries)
        return _MateGeometry(
            body.vertices, base.vertices, rest_obj, sweep,
            0.5 * (mate.part_span[0] + mate.part_span[1]), part_feature, base_feature,
            base_rest, pairs)

    def _models(self, part: str, geometry: _MateGeometry, mode: CheckMode):
        """The part's model and the base's object that ``mode`` compares, and the triangles
        of each."""
        if mode is KEEP_COPLANAR:
            return (geometry.part_feature(), geometry.base_feature(),
                    geometry.part_feature_faces, geometry.base_feature_faces)
        body = self._bodies[part]
        base_faces = self._base_faces if mode is NOCARE_COPLANAR \
            else geometry.base_rest_faces
        other = self._whole() if mode is NOCARE_COPLANAR else geometry.base_rest
        return self._model(part), other, body.faces, base_faces

    def base_distance(self, part: str, mate: int, base_from_part: sp.Pose,
                      mode: CheckMode, *, lift: sp.Vec3 = sp.ZERO3) -> float:
        """Distance from the posed part to the base under a section-6 mode (base axes).

        ``inf`` when the mode leaves nothing of the base to check against.
        """
        geometry = self._mate(part, mate)
        pose = sp.Pose(sp.add(base_from_part.position, lift), base_from_part.rotation)
        if mode is SKIP_COAXIAL and geometry.fit_pairs is not None:
            transform = _transform(pose)
            d = float("inf")
            for model, other, _, _, gap in geometry.fit_pairs:
                if gap >= d:
                    continue  # no nearer than the distance found: cannot lower it
                self.stats["fcl_distance_queries"] += 1
                d = min(d, _distance(fcl.CollisionObject(
                    self._model(part) if model is None else model, transform), other))
            return d
        model, other, _, _ = self._models(part, geometry, mode)
        if model is None or other is None:
            return float("inf")
        self.stats["fcl_distance_queries"] += 1
        return _distance(fcl.CollisionObject(model, _transform(pose)), other)

    def axial_split(self, part: str, mate: int, base_from_part: sp.Pose, apart: float,
                    near: float) -> AxialSplit:
        """``SKIP_COAXIAL``'s faces split for the posed part moved along the axis
        constraint's base axis (``AxialSplit``): base faces radially farther than ``apart``
        from the part's are left out of ``blocking``; those under ``near`` are ``passing``.
        The base's radial and axial extents are asked once per constraint; the models built
        for a split are kept for the next with the same faces (an approach's turns)."""
        geometry = self._mate(part, mate)
        body = self._bodies[part]
        assert body.assembly is not None
        m = body.assembly.mates[mate]
        point, axis = m.base_points[0], m.base_dirs[0]
        if geometry.fit_pairs is not None:
            queries = [(q[0], q[2], q[3]) for q in geometry.fit_pairs]
        elif geometry.base_rest is not None and len(body.faces):
            queries = [(None, body.faces, geometry.base_rest_faces)]
        else:
            queries = []
        posed = posed_points(body.vertices, base_from_part)
        u = np.asarray(axis, dtype=np.float64)
        along = dots(posed - np.asarray(point, dtype=np.float64), u)
        blocking: list = []
        passing: list = []
        far_gap = math.inf
        for k, (model, faces_p, faces_b) in enumerate(queries):
            extent = self._axial_extents.get((part, mate, k))
            if extent is None:
                lo_b, hi_b = radial_extent(self._base_vertices, faces_b, point, axis)
                z = dots(self._base_vertices - np.asarray(point, dtype=np.float64), u)[faces_b]
                extent = self._axial_extents[(part, mate, k)] = (
                    lo_b, hi_b, z.min(axis=1), z.max(axis=1), z.mean(axis=1))
            lo_b, hi_b, z_lo, z_hi, z_mid = extent
            lo_p, hi_p = radial_extent(posed, faces_p, point, axis)
            gap = np.maximum(np.maximum(lo_b - float(hi_p.max()), float(lo_p.min()) - hi_b),
                             0.0)
            apart_of = gap > apart
            blocking.append((model, self._split_object(part, mate, k, "blocking", ~apart_of,
                                                       faces_b)))
            far = apart_of & (gap >= near)
            if far.any():
                far_gap = min(far_gap, float(gap[far].min()))
            close = apart_of & (gap < near)
            if close.any():
                z_p = along[faces_p]
                passing.append(_Passing(
                    model, self._split_object(part, mate, k, "passing", close, faces_b),
                    gap[close], z_lo[close], z_hi[close], z_mid[close], lo_b[close],
                    hi_b[close], z_p.min(axis=1), z_p.max(axis=1), lo_p, hi_p))
        return AxialSplit(blocking, passing, far_gap,
                          all(len(faces_b) == 0 for _, _, faces_b in queries))

    def passed_distance(self, part: str, split: AxialSplit, base_from_part: sp.Pose,
                        axis: sp.Vec3, t_lo: float, t_hi: float,
                        near: float) -> tuple[float, float]:
        """How near the split's ``passing`` faces the part comes moved from its pose by
        ``t`` times the base ``axis`` (a unit vector), ``t_lo <= t <= t_hi``: a lower bound
        and a distance met. No point of the part comes nearer a face than the face's radial
        gap and its gap along the axis to the part's span together (the radial and axial
        distances of two points are no more than their distance). Each query's face
        nearest by that bound (under ``near``: else only the bound is given) is asked of fcl
        with the part moved to put its middle within the span along the axis of the part
        face nearest it radially, over the longest stretch of offsets that does: the
        distance is inf where no face was asked, NaN where one to be asked is beside no
        such part face within the interval."""
        bound = met = math.inf
        for q in split.passing:
            low, high = float(q.part_z_lo.min()), float(q.part_z_hi.max())
            # The face's gap along the axis to the part's span swept over [t_lo, t_hi].
            sep = np.maximum(np.maximum(q.z_lo - (high + t_hi), (low + t_lo) - q.z_hi), 0.0)
            lower = np.sqrt(q.gap * q.gap + sep * sep)
            i = int(np.argmin(lower))
            bound = min(bound, float(lower[i]))
            if float(lower[i]) >= near:
                continue
            # The nearest by the bound first; where the part faces nearest it radially are
            # beside it only off the interval (a counterbore's floor, beside the shoulder
            # only in the last 2 mm), the next unlike it (its radial extent and middle
            # along the axis): its wall is. Any t of the interval gives a distance met.
            order = np.argsort(lower, kind="stable")
            order = order[lower[order] < near]
            keys = np.round(np.stack([q.r_lo[order], q.r_hi[order], q.z_mid[order]], axis=1)
                            / _RING_KEY_M)
            _, first = np.unique(keys, axis=0, return_index=True)
            found = False
            t = 0.0
            for candidate in order[np.sort(first)][:_PASSED_TRIES].tolist():
                i = int(candidate)
                pair = np.maximum(np.maximum(float(q.r_lo[i]) - q.part_r_hi,
                                             q.part_r_lo - float(q.r_hi[i])), 0.0)
                nearest = pair <= float(pair.min())
                a = np.maximum(float(q.z_mid[i]) - q.part_z_hi[nearest], t_lo)
                b = np.minimum(float(q.z_mid[i]) - q.part_z_lo[nearest], t_hi)
                j = int(np.argmax(b - a))
                if float(b[j]) >= float(a[j]):
                    t = 0.5 * (float(a[j]) + float(b[j]))
                    found = True
                    break
            if not found:
                return bound, math.nan
            moved = sp.Pose(sp.add(base_from_part.position, sp.scale(axis, t)),
                            base_from_part.rotation)
            met = min(met, self.split_distance(part, [(q.model, q.obj)], moved))
        return bound, met

    def _split_object(self, part: str, mate: int, k: int, kind: str, mask: np.ndarray,
                      faces_b: np.ndarray) -> fcl.CollisionObject | None:
        """The base object of ``faces_b[mask]`` (None: no faces), built once per faces."""
        key = (part, mate, k, kind, np.packbits(mask).tobytes())
        if key not in self._split_objects:
            model = _bvh_of(self._base_vertices, faces_b[mask])
            self._split_objects[key] = None if model is None else fcl.CollisionObject(
                model, self._identity)
        return self._split_objects[key]

    def split_distance(self, part: str, pairs: list, base_from_part: sp.Pose) -> float:
        """The least distance of the posed part's pairs (``AxialSplit.blocking``, or one of
        ``passing`` in a list); inf where none has base faces."""
        transform = _transform(base_from_part)
        d = float("inf")
        for model, other in pairs:
            if other is None:
                continue
            self.stats["fcl_distance_queries"] += 1
            d = min(d, _distance(fcl.CollisionObject(
                self._model(part) if model is None else model, transform), other))
        return d

    def base_distance_within(self, part: str, mate: int, base_from_part: sp.Pose,
                             mode: CheckMode, tol: float, *,
                             lift: sp.Vec3 = sp.ZERO3) -> float:
        """``base_distance`` where only "is it within ``tol``?" is asked of an answer <= tol.

        The distance of two meshes is the least distance of a pair of their triangles, so
        while the pair that last came within ``tol`` (its witness) is still within it, so
        are the meshes: that pair's distance (<= tol, and >= the meshes') is returned after
        one triangle-to-triangle query instead of the whole meshes' (a part lying flat
        against the base has hundreds of triangles at the same distance, which no bounding
        volume prunes). Any answer > tol is the exact ``base_distance``.
        """
        geometry = self._mate(part, mate)
        model, other, part_faces, base_faces = self._models(part, geometry, mode)
        pairs = geometry.fit_pairs if mode is SKIP_COAXIAL else None
        if pairs is None and (model is None or other is None):
            return float("inf")
        pose = sp.Pose(sp.add(base_from_part.position, lift), base_from_part.rotation)
        transform = _transform(pose)
        key = (part, mate, mode)
        witness = self._witnesses.get(key) if _WITNESS_PAIRS else None
        if witness is not None:
            self.stats["witness_tests"] += 1
            d = _distance(fcl.CollisionObject(witness[0], transform), witness[1])
            if d <= tol - _WITNESS_MARGIN_M:
                return d
        result = fcl.DistanceResult()
        if pairs is None:
            self.stats["fcl_distance_queries"] += 1
            d = fcl.distance(fcl.CollisionObject(model, transform), other,
                             fcl.DistanceRequest(), result)
        else:
            # The nearest of the fit's queries, and its triangles for the witness.
            d = float("inf")
            for model, other, faces_p, faces_b, gap in pairs:
                if gap >= d:
                    continue  # no nearer than the distance found: cannot lower it
                self.stats["fcl_distance_queries"] += 1
                found = fcl.DistanceResult()
                d_pair = fcl.distance(fcl.CollisionObject(
                    self._model(part) if model is None else model, transform), other,
                    fcl.DistanceRequest(), found)
                if d_pair < d:
                    d, result, part_faces, base_faces = d_pair, found, faces_p, faces_b
        if d <= tol and 0 <= result.b1 < len(part_faces) and 0 <= result.b2 < len(base_faces):
            body, base = self._bodies[part], self._base_vertices
            self._witnesses[key] = (
                _bvh_of(body.vertices, part_faces[result.b1:result.b1 + 1]),
                fcl.CollisionObject(_bvh_of(base, base_faces[result.b2:result.b2 + 1]),
                                    fcl.Transform()))
        elif witness is not None:
            del self._witnesses[key]  # out of contact: no pair test until it touches again
        return d

    def support_distance(self, part: str, mate: int, point: sp.Vec3) -> float:
        """Distance from a point on the base plane to the base's feature faces (0: on them)."""
        geometry = self._mate(part, mate)
        feature = geometry.base_feature()
        if feature is None:
            return float("inf")
        self.stats["fcl_distance_queries"] += 1
        probe = fcl.CollisionObject(self._probe, fcl.Transform(np.array(point, dtype=np.float64)))
        return _distance(probe, feature)

    def stand_in(self, part: str, mate: int, plane: int,
                 tol: float) -> tuple[sp.Vec3 | None, bool]:
        """What stands for the part's centre of mass on its side of the plane mate's
        ``plane`` when asking what holds it up (``step._unsupported``), and whether the
        part's own faces there (or its line of contact: a rod on a line of its facets) cover
        that point, within ``tol``. The point is None for the centre of mass dropped onto
        the plane, as for most parts; for one whose centre of mass overhangs the hull of its
        footprint (the part's vertices in the plane: an L-shaped part, its arm out past its
        foot) it is that hull's point nearest the centre of mass (part frame): a part held
        on a plain plate (nothing here tips a part) is held as well where a hole or slot,
        or the plate's edge, is under its arm and not under its foot (an L "slid off" into
        a groove under its arm and rested 19.9 mm inside the plate). Not covered (a U-shaped
        part's notch), the base's faces under that point may touch nothing of the part (a
        review: a U held by a rib under its notch, an L by the plate under its arm, its
        foot wholly over a groove). Found once a part and plane, in the part's frame."""
        key = (part, mate, plane)
        found = self._stand_ins.get(key)
        if found is not None:
            return found
        body = self._bodies[part]
        assert body.assembly is not None
        m = body.assembly.mates[mate]
        vertices = np.asarray(body.vertices, dtype=np.float64)
        faces = np.asarray(body.faces)
        point = np.array(m.part_points[plane], dtype=np.float64)
        normal = np.array(sp.normalize(m.part_dirs[plane]), dtype=np.float64)
        own = support.plane_basis(normal)
        cm = _flat2(np.array([body.center_of_mass], dtype=np.float64), point, own)[0]
        footprint = _flat2(vertices[np.abs(support.along(vertices - point, normal)) <= tol],
                           point, own)
        stand: sp.Vec3 | None = None
        at = cm
        if len(footprint):
            overhang, x, y = support.nearest_in_hull(cm, support.convex_hull(footprint))
            if overhang > _OVERHANG_MIN_M:
                at = np.array([x, y])
                stand = (float(point[0] + x * own[0][0] + y * own[1][0]),
                         float(point[1] + x * own[0][1] + y * own[1][1]),
                         float(point[2] + x * own[0][2] + y * own[1][2]))
        flat = faces[support.in_plane(vertices, faces, point, normal, tol)]
        triangles = _flat2(vertices[flat.ravel()], point, own).reshape(-1, 3, 2)
        if len(flat):
            covered = support.distance_to_pieces(at, triangles, np.zeros((0, 2, 2))) <= tol
        else:  # no face in the plane: its line of contact, if any
            edges = vertices[support.plane_edges(vertices, faces, point, normal, tol)]
            covered = support.distance_to_pieces(at, triangles, _flat2(
                edges.reshape(-1, 3), point, own).reshape(-1, 2, 2)) <= tol
        found = self._stand_ins[key] = (stand, bool(covered))
        return found

    def support_gap(self, part: str, mate: int, plane: int, foot: sp.Vec3,
                    base_from_part: sp.Pose, tol: float, beyond: float = 0.0) -> float:
        """How far ``foot`` (the centre of mass dropped onto the plane mate's ``plane``, base
        axes) lies outside the convex hull of where the part's faces or edges in that plane
        (within ``tol``) meet the plane's faces: 0 within it, ``inf`` where they do not meet
        (``support``). Where the foot is off the faces (``support_distance``) over a hole or
        a slot the part spans, it is held still. ``inf`` at once where the foot is
        ``beyond`` or farther outside the hull of all the plane's faces (past a plate's
        outer edge: nothing of the part's can hold it nearer; ~20 us, not ~0.4 ms)."""
        body = self._bodies[part]
        geometry = self._mate(part, mate)
        assert body.assembly is not None
        m = body.assembly.mates[mate]
        held = self._support_planes.get((part, mate, plane))
        if held is None:
            # The plane's outline first: the hull of its faces' corners, to ask where the
            # foot is (past a plate's outer edge that settles it).
            point = np.array(m.base_points[plane], dtype=np.float64)
            normal = np.array(sp.normalize(m.base_dirs[plane]), dtype=np.float64)
            basis = support.plane_basis(normal)
            faces = geometry.base_feature_faces
            flat = faces[support.in_plane(self._base_vertices, faces, point, normal, tol)]
            outline = support.convex_hull(_flat2(self._base_vertices[flat.ravel()], point,
                                                 basis))
            held = self._support_planes[(part, mate, plane)] = _SupportPlane(
                point, normal, basis, outline)
        rel = [foot[0] - float(held.point[0]), foot[1] - float(held.point[1]),
               foot[2] - float(held.point[2])]
        foot_2d = (sum(r * float(b) for r, b in zip(rel, held.basis[0])),
                   sum(r * float(b) for r, b in zip(rel, held.basis[1])))
        if support.distance_outside(foot_2d, held.outline) >= beyond:
            return math.inf
        detail = held.detail
        if detail is None:
            # The plane's boundary and corners, and the part's boundary (or line) and faces
            # in its plane: the first time the outline does not settle it.
            edges = self._base_vertices[support.plane_edges(
                self._base_vertices, geometry.base_feature_faces, held.point, held.normal,
                tol)]
            vertices, faces = np.asarray(body.vertices), np.asarray(body.faces)
            part_point = np.array(m.part_points[plane], dtype=np.float64)
            part_normal = np.array(sp.normalize(m.part_dirs[plane]), dtype=np.float64)
            flat = faces[support.in_plane(vertices, faces, part_point, part_normal, tol)]
            model = _bvh_of(vertices, flat) if len(flat) else None
            detail = held.detail = _SupportDetail(
                held.flat2(edges.reshape(-1, 3)).reshape(-1, 2, 2),
                np.unique(edges.reshape(-1, 3), axis=0),
                vertices[support.plane_edges(vertices, faces, part_point, part_normal, tol)],
                None if model is None else fcl.CollisionObject(model, self._identity))
        if len(detail.part_edges) == 0:
            return math.inf
        posed = posed_points(detail.part_edges.reshape(-1, 3), base_from_part)
        part_2d = held.flat2(posed).reshape(-1, 2, 2)
        found = [support.crossings(part_2d, detail.boundary)]
        # The part's corners on the plane's faces.
        inside = [p for p in np.unique(posed, axis=0)
                  if self.support_distance(part, mate, (float(p[0]), float(p[1]),
                                                        float(p[2]))) <= tol]
        if inside:
            found.append(held.flat2(np.array(inside)))
        if detail.part_flat is not None and len(detail.corners):
            # The plane's corners under the part's faces (asked in the part's frame).
            theirs = held.flat2(detail.corners)
            flat_2d = part_2d.reshape(-1, 2)
            box = np.all((theirs >= flat_2d.min(axis=0) - tol)
                         & (theirs <= flat_2d.max(axis=0) + tol), axis=1)
            under = []
            for i, p in zip(np.nonzero(box)[0],
                            posed_points(detail.corners[box], base_from_part.inverse())):
                self.stats["fcl_distance_queries"] += 1
                if _distance(fcl.CollisionObject(self._probe, fcl.Transform(p)),
                             detail.part_flat) <= tol:
                    under.append(i)
            if under:
                found.append(theirs[under])
        return support.support_gap(foot_2d, np.concatenate(found))

    def sweep_clearance(self, part: str, mate: int, axis_point: sp.Vec3,
                        axis_rotation: sp.Quat) -> float:
        """Distance from the part's solid of revolution about the shaft to the rest of the
        base: while positive, no angle of the part can touch it. ``axis_point`` is where the
        part's own axis point sits (base axes); ``axis_rotation`` takes z onto the shaft."""
        geometry = self._mate(part, mate)
        rest, floor = geometry.base_rest, float("inf")
        if geometry.fit_pairs is not None:
            # Radial fits: the solid against the base's bulk (what no group of the part's
            # faces leaves out), and for the rest each query's radial gap, which no turn
            # or slide along the axis changes (a shaft inside the part's bore lies inside
            # its solid of revolution, and is met by none of the faces near it).
            bulk = [q for q in geometry.fit_pairs if q[0] is None]
            rest = bulk[0][1] if bulk else None
            floor = min((q[4] for q in geometry.fit_pairs if q[0] is not None),
                        default=float("inf"))
        if rest is None:
            return floor
        center = sp.add(axis_point, sp.quat_rotate(axis_rotation,
                                                   (0.0, 0.0, geometry.sweep_center)))
        self.stats["fcl_distance_queries"] += 1
        cylinder = fcl.CollisionObject(geometry.sweep, _transform(sp.Pose(center, axis_rotation)))
        return min(floor, _distance(cylinder, rest))

    def _surfaces(self) -> list[_Surface]:
        """The base's faces in surfaces (``base_surfaces``), each with its box, built the
        first time a part leaves the base (``surfaces_within``)."""
        if self._base_surfaces is None:
            labels = base_surfaces(self._base_vertices, self._base_faces)
            order = np.argsort(labels, kind="stable")
            starts = np.flatnonzero(np.r_[True, labels[order][1:] != labels[order][:-1]])
            corners = self._base_vertices[self._base_faces]
            self._base_surfaces = []
            for group in np.split(order, starts[1:]):
                c = corners[group].reshape(-1, 3)
                lo, hi = c.min(axis=0), c.max(axis=0)
                self._base_surfaces.append(_Surface(
                    group, (float(lo[0]), float(lo[1]), float(lo[2])),
                    (float(hi[0]), float(hi[1]), float(hi[2]))))
        return self._base_surfaces

    def _surface_object(self, index: int,
                        mate: tuple[str, int] | None = None) -> fcl.CollisionObject | None:
        """A surface's BVH; with ``mate`` (part, constraint), of its faces that constraint's
        SKIP checks keep (``_MateGeometry.base_rest_faces``; None where none is)."""
        surface = self._surfaces()[index]
        if mate is None:
            if surface.obj is None:
                surface.obj = fcl.CollisionObject(
                    _bvh_of(self._base_vertices, self._base_faces[surface.faces]),
                    fcl.Transform())
            return surface.obj
        key = (mate[0], mate[1], index)
        if key not in self._rest_surfaces:
            # (By face index: ``_MateGeometry.base_rest_faces`` holds the faces' corners, and
            # intersecting with those kept faces whose index is some corner's: a review.)
            assembly = self._bodies[mate[0]].assembly
            kept = assembly.mates[mate[1]].base_rest_faces  # type: ignore[union-attr]
            faces = np.intersect1d(surface.faces, kept)
            model = _bvh_of(self._base_vertices, self._base_faces[faces])
            self._rest_surfaces[key] = None if model is None \
                else fcl.CollisionObject(model, fcl.Transform())
        return self._rest_surfaces[key]

    def rest_surfaces_within(self, part: str, mate: int, base_from_part: sp.Pose,
                             within: float, *, lift: sp.Vec3 = sp.ZERO3) -> tuple[int, ...]:
        """The surfaces (``base_surfaces``) of what a constraint's SKIP checks keep of the
        base within ``within`` of the posed part: what a part passing the base within the
        tolerance comes near (``step._passing``)."""
        pose = sp.Pose(sp.add(base_from_part.position, lift), base_from_part.rotation)
        obj = fcl.CollisionObject(self._model(part), _transform(pose))
        near = []
        for _, index in self._nearest_surfaces(part, pose, (), within):
            other = self._surface_object(index, (part, mate))
            if other is not None:
                self.stats["fcl_distance_queries"] += 1
                if _distance(obj, other) <= within:
                    near.append(index)
        return tuple(sorted(near))

    def sweeps_by_surface(self, part: str, mate: int) -> bool:
        """Whether the constraint's SKIP checks can be asked surface by surface
        (``rest_nearest_without``): not where it has radial fits
        (``_MateGeometry.fit_pairs``), which whole surfaces do not see (a pin passing its
        rim would meet it)."""
        return self._mate(part, mate).fit_pairs is None

    def rest_nearest_without(self, part: str, mate: int, base_from_part: sp.Pose,
                             without: tuple[int, ...], *,
                             lift: sp.Vec3 = sp.ZERO3) -> tuple[float, int]:
        """``base_distance`` under the constraint's SKIP mode without the surfaces
        ``without`` lists (what a part touches as a move starts in contact, which it may
        move along), and the nearest surface (-1 where none is left); only where
        ``sweeps_by_surface``."""
        pose = sp.Pose(sp.add(base_from_part.position, lift), base_from_part.rotation)
        best, _, which = self._graced_nearest(part, pose, without, False, (part, mate))
        return best, which

    def rest_distance(self, part: str, mate: int, base_from_part: sp.Pose,
                      only: tuple[int, ...], *, lift: sp.Vec3 = sp.ZERO3) -> float:
        """``base_distance`` under a SKIP mode to the surfaces ``only`` lists alone."""
        pose = sp.Pose(sp.add(base_from_part.position, lift), base_from_part.rotation)
        return self._graced_nearest(part, pose, (), False, (part, mate), only)[0]

    def _part_box(self, part: str, base_from_part: sp.Pose) -> tuple[sp.Vec3, sp.Vec3]:
        body = self._bodies[part]
        lo, hi = body.bbox_min, body.bbox_max
        corners = [base_from_part.apply((x, y, z)) for x in (lo[0], hi[0])
                   for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]
        return ((min(c[0] for c in corners), min(c[1] for c in corners),
                 min(c[2] for c in corners)),
                (max(c[0] for c in corners), max(c[1] for c in corners),
                 max(c[2] for c in corners)))

    def _nearest_surfaces(self, part: str, base_from_part: sp.Pose,
                          grace: tuple[int, ...], within: float = float("inf"),
                          only: tuple[int, ...] | None = None):
        """The surfaces not in ``grace`` (of those ``only`` lists) nearest the posed part,
        nearest box first, with each one's box gap (a lower bound of its distance), those
        within ``within``."""
        self.stats["bounding_tests"] += 1
        lo, hi = self._part_box(part, base_from_part)
        out = []
        surfaces = self._surfaces()
        for index in (range(len(surfaces)) if only is None else only):
            surface = surfaces[index]
            if index in grace:
                continue
            gap = math.sqrt(sum(max(0.0, surface.lo[k] - hi[k], lo[k] - surface.hi[k]) ** 2
                                for k in range(3)))
            if gap <= within:
                out.append((gap, index))
        out.sort()
        return out

    def surfaces_within(self, part: str, base_from_part: sp.Pose,
                        within: float) -> tuple[int, ...]:
        """The base's surfaces (``base_surfaces``: faces joined at folds under 30 degrees)
        within ``within`` of the posed part, ascending: the surfaces a part touches as it
        leaves the base, which its flight passes while leaving (``Flight.grace``). Whole
        surfaces, so that a finely meshed face does not hold the part by the triangle next
        to the one it touched."""
        return self.surface_gaps(part, base_from_part, within)[0]

    def surface_gaps(self, part: str, base_from_part: sp.Pose, within: float
                     ) -> tuple[tuple[int, ...], tuple[float, ...]]:
        """``surfaces_within``, and each one's distance from the posed part (what a flight
        leaving the base keeps, ``Flight.grace_gaps``)."""
        if self._base is None:
            return (), ()
        obj = fcl.CollisionObject(self._model(part), _transform(base_from_part))
        near = []
        for _, index in self._nearest_surfaces(part, base_from_part, (), within):
            self.stats["fcl_distance_queries"] += 1
            d = _distance(obj, self._surface_object(index))  # type: ignore[arg-type]
            if d <= within:
                near.append((index, d))
        near.sort()
        return tuple(i for i, _ in near), tuple(d for _, d in near)

    def flat_plane(self, index: int) -> tuple[sp.Vec3, float] | None:
        """The plane of one of the base's surfaces that is flat (each face's normal within
        ``_FLAT_COS`` of their area-weighted mean): its normal (base axes) as the faces'
        winding has it, outward for the meshes the scene builds, and its offset along it
        (the plane is ``dot(normal, x) == offset``); None for a curved one (a bore's wall)."""
        surface = self._surfaces()[index]
        if not surface.flat_known:
            tri = self._base_vertices[self._base_faces[surface.faces]]
            areas = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])  # 2 x area x normal
            total = areas.sum(axis=0)
            length = float(math.sqrt(float(total[0]) ** 2 + float(total[1]) ** 2
                                     + float(total[2]) ** 2))
            surface.flat_known = True
            if length > 0.0:
                mean = (float(total[0]) / length, float(total[1]) / length,
                        float(total[2]) / length)
                sizes = norms(areas)
                along = (areas[:, 0] * mean[0] + areas[:, 1] * mean[1]
                         + areas[:, 2] * mean[2])
                if bool(np.all(along >= _FLAT_COS * sizes)):
                    corner = tri[0, 0]
                    surface.flat = (mean, mean[0] * float(corner[0])
                                    + mean[1] * float(corner[1]) + mean[2] * float(corner[2]))
        return surface.flat

    def depth_in_flat(self, part: str, base_from_part: sp.Pose, index: int,
                      normal: sp.Vec3, reach: float) -> float | None:
        """How far the posed part lies inside flat surface ``index`` (outward ``normal``,
        ``flat_plane``) along that normal: moved out ``reach`` along it, how much nearer
        than ``reach`` it still is (fcl tells no depth of meshes that overlap; it tells a
        distance). None where it is deeper than ``reach``."""
        moved = sp.Pose(sp.add(base_from_part.position, sp.scale(normal, reach)),
                        base_from_part.rotation)
        d = self.surface_distance(part, moved, index)
        return reach - d if d > 0.0 else None

    def surface_distance(self, part: str, base_from_part: sp.Pose, index: int) -> float:
        """Distance from the posed part to one of the base's surfaces (``base_surfaces``)."""
        return self.surface_distances(part, base_from_part, (index,))[0]

    def surface_distances(self, part: str, base_from_part: sp.Pose,
                          surfaces: tuple[int, ...]) -> list[float]:
        """``surface_distance`` to each of ``surfaces``, with one posed part."""
        obj = fcl.CollisionObject(self._model(part), _transform(base_from_part))
        out = []
        for index in surfaces:
            self.stats["fcl_distance_queries"] += 1
            out.append(_distance(obj, self._surface_object(index)))  # type: ignore[arg-type]
        return out

    def _graced_nearest(self, part: str, base_from_part: sp.Pose, grace: tuple[int, ...],
                        nearest_points: bool, mate: tuple[str, int] | None = None,
                        only: tuple[int, ...] | None = None):
        """The distance to the base (with ``mate``, what that constraint's SKIP checks keep
        of it) without the surfaces ``grace`` lists (or to those ``only`` lists), and the
        fcl result and surface of it (``inf``, None, -1 where none is left)."""
        obj = fcl.CollisionObject(self._model(part), _transform(base_from_part))
        best, found, which = float("inf"), None, -1
        for gap, index in self._nearest_surfaces(part, base_from_part, grace, only=only):
            if gap >= best:
                break  # boxes sorted by gap: nothing farther can be nearer
            other = self._surface_object(index, mate)
            if other is None:
                continue
            self.stats["fcl_distance_queries"] += 1
            result = fcl.DistanceResult()
            d = fcl.distance(obj, other,
                             fcl.DistanceRequest(enable_nearest_points=nearest_points), result)
            if d < best:
                best, found, which = d, result, index
        return best, found, which

    def distance_to_base(self, part: str, base_from_part: sp.Pose,
                         grace: tuple[int, ...] | None = None) -> float:
        """Distance from the part, posed in the base frame, to the whole base part; with
        ``grace``, to the base without those surfaces (``surfaces_within``; ``inf`` where
        none is left)."""
        if self._base is None:
            return float("inf")
        if grace:
            return self._graced_nearest(part, base_from_part, grace, False)[0]
        self.stats["fcl_distance_queries"] += 1
        return _distance(fcl.CollisionObject(self._model(part), _transform(base_from_part)),
                         self._whole())

    def base_contact(self, part: str, base_from_part: sp.Pose,
                     grace: tuple[int, ...] | None = None, only: tuple[int, ...] | None = None
                     ) -> tuple[sp.Vec3 | None, bool, sp.Vec3]:
        """The unit direction from the base's nearest point to the part's (base axes: the
        normal of the face the part touches, of the base without the surfaces ``grace``
        lists, or of those ``only`` lists alone; None when they overlap, no nearest points);
        whether it is a face's: within 30 degrees of the normal of the base triangle nearest
        the part, not the direction from an edge or a corner (a part leaving the base along
        a face meets the edge of another surface flush with it, a seam in a wall, at
        directions between the two); and the part's point nearest the base (base axes;
        where a graze acts, ``step._graze``; the origin with no normal)."""
        if self._base is None:
            return None, False, sp.ZERO3
        faces = self._base_faces
        if grace or only is not None:
            d, result, which = self._graced_nearest(part, base_from_part, grace or (), True,
                                                    only=only)
            if result is None:
                return None, False, sp.ZERO3
            faces = faces[self._surfaces()[which].faces]
        else:
            self.stats["fcl_distance_queries"] += 1
            result = fcl.DistanceResult()
            d = fcl.distance(fcl.CollisionObject(self._model(part),
                                                 _transform(base_from_part)),
                             self._whole(), fcl.DistanceRequest(enable_nearest_points=True),
                             result)
        if not d > 0.0:
            return None, False, sp.ZERO3
        on_part, on_base = result.nearest_points
        gap = sp.sub((float(on_part[0]), float(on_part[1]), float(on_part[2])),
                     (float(on_base[0]), float(on_base[1]), float(on_base[2])))
        if not sp.norm(gap) > 0.0:
            return None, False, sp.ZERO3
        normal = sp.normalize(gap)
        on_face = False
        if 0 <= result.b2 < len(faces):
            a, b, c = ((float(v[0]), float(v[1]), float(v[2]))
                       for v in (self._base_vertices[i] for i in faces[result.b2]))
            n = sp.cross(sp.sub(b, a), sp.sub(c, a))
            length = sp.norm(n)
            on_face = length > 0.0 and abs(sp.dot(normal, (n[0] / length, n[1] / length,
                                                           n[2] / length))) >= _FACE_COS
        return normal, on_face, (float(on_part[0]), float(on_part[1]), float(on_part[2]))

    def environment_near(self, center: sp.Vec3, radius: float) -> tuple[int, ...]:
        """Indices of environment objects whose world box a sphere can touch."""
        self.stats["bounding_tests"] += 1
        near = []
        for index, fixed in enumerate(self._fixed):
            gap = 0.0
            for axis in range(3):
                # (Products, not ``** 2``: compiled, a float's power is a generic call. A
                # filter: an fcl query follows where it passes, whose answer decides.)
                c = center[axis]
                if c < fixed.lo[axis]:
                    e = fixed.lo[axis] - c
                    gap += e * e
                elif c > fixed.hi[axis]:
                    e = c - fixed.hi[axis]
                    gap += e * e
            if gap <= radius * radius:
                near.append(index)
        return tuple(near)

    def environment_near_box(self, lo: sp.Vec3, hi: sp.Vec3) -> tuple[int, ...]:
        """Indices of environment objects whose world box meets the box ``lo``-``hi``."""
        self.stats["bounding_tests"] += 1
        near = []
        for index, fixed in enumerate(self._fixed):
            if all(lo[k] <= fixed.hi[k] and fixed.lo[k] <= hi[k] for k in range(3)):
                near.append(index)
        return tuple(near)

    def inside_environment(self, part: str, pose: sp.Pose,
                           candidates: tuple[int, ...]) -> int:
        """The first of ``candidates`` whose closed mesh the posed part lies wholly inside,
        or -1. fcl's distance between two meshes is the gap between their surfaces, so a
        part wholly inside the table is at a distance from it, not touching it (a trial: a
        part let go inside the table fell through it). Asked where the part is clear of the
        candidates' surfaces (wholly inside or wholly outside each): one vertex of it says
        which (``arrays.winding``)."""
        body = self._bodies[part]
        first = body.vertices[0]
        point = pose.apply((float(first[0]), float(first[1]), float(first[2])))
        for index in candidates:
            fixed = self._fixed[index]
            if not all(fixed.lo[k] < point[k] < fixed.hi[k] for k in range(3)):
                continue
            # A solid (every edge two triangles') has an inside to be in: found the first
            # time a part is asked to be in it, not at every start.
            solid = self._solid.get(index)
            if solid is None:
                solid = self._solid[index] = closed(np.asarray(fixed.body.faces))
            if not solid:
                continue
            other = fixed.body
            local = other.initial_pose.inverse().apply(point)
            if winding(other.vertices, other.faces, np.array([local]))[0] > 0.5:
                return index
        return -1

    def environment_normal(self, part: str, pose: sp.Pose, index: int) -> sp.Vec3 | None:
        """The unit direction from environment object ``index``'s nearest point to the
        posed part's (world axes: the normal of the face it touches, or the direction from
        an edge), or None where the two overlap (no nearest points)."""
        self.stats["fcl_distance_queries"] += 1
        result = fcl.DistanceResult()
        d = fcl.distance(fcl.CollisionObject(self._model(part), _transform(pose)),
                         self._fixed[index].obj, fcl.DistanceRequest(enable_nearest_points=True),
                         result)
        if not d > 0.0:
            return None
        a, b = result.nearest_points
        gap = (float(a[0]) - float(b[0]), float(a[1]) - float(b[1]), float(a[2]) - float(b[2]))
        length = sp.norm(gap)
        return sp.scale(gap, 1.0 / length) if length > 0.0 else None

    def environment_name(self, index: int) -> str:
        return self._fixed[index].name

    def distance_between_parts(self, a: str, pose_a: sp.Pose, b: str,
                               pose_b: sp.Pose) -> float:
        """Distance between two posed parts (0 touching or overlapping, a gap between
        nested meshes). Parts do not collide with each other in the step: this is for the
        checks of a scene at its start (``replay.scene_warnings``)."""
        self.stats["fcl_distance_queries"] += 1
        return _distance(fcl.CollisionObject(self._model(a), _transform(pose_a)),
                         fcl.CollisionObject(self._model(b), _transform(pose_b)))

    def point_distance(self, part: str, point: sp.Vec3, base: bool = False) -> float:
        """Distance from a point (the part's own axes) to the part's surface; with ``base``
        to the base part's (its axes; ``inf`` without one)."""
        self.stats["fcl_distance_queries"] += 1
        probe = fcl.CollisionObject(self._probe, fcl.Transform(np.array(point,
                                                                         dtype=np.float64)))
        if base:
            return float("inf") if self._base is None else _distance(probe, self._whole())
        return _distance(probe, fcl.CollisionObject(self._model(part), fcl.Transform()))

    def distance_to_environment(self, part: str, pose: sp.Pose,
                                candidates: tuple[int, ...]) -> tuple[float, int]:
        """Smallest distance from the posed part to the candidates (<= 0 when touching)."""
        obj = fcl.CollisionObject(self._model(part), _transform(pose))
        best, which = float("inf"), -1
        for index in candidates:
            self.stats["fcl_distance_queries"] += 1
            result = fcl.DistanceResult()
            d = fcl.distance(obj, self._fixed[index].obj, fcl.DistanceRequest(), result)
            if d < best:
                best, which = d, index
        return best, which
