"""Collision queries with python-fcl; the only module that imports fcl.

``CollisionWorld`` builds every BVH once from the Scene. A query first runs a cheap
bounding test (a sphere around the part's centre of mass against each object's world
box) and asks fcl only for the objects that can touch. ``stats`` counts what was asked,
for the replay summary; it is instrumentation and never feeds back into the simulation.
"""

from __future__ import annotations

from dataclasses import dataclass

import fcl
import numpy as np

from . import spatial as sp
from .scene import Body, Scene


def _bvh(body: Body) -> fcl.BVHModel:
    model = fcl.BVHModel()
    model.beginModel(len(body.vertices), len(body.faces))
    model.addSubModel(np.ascontiguousarray(body.vertices), np.ascontiguousarray(body.faces))
    model.endModel()
    return model


def _transform(pose: sp.Pose) -> fcl.Transform:
    x, y, z, w = pose.rotation
    return fcl.Transform(np.array([w, x, y, z]), np.array(pose.position, dtype=np.float64))


@dataclass(frozen=True)
class _Fixed:
    name: str
    obj: fcl.CollisionObject
    lo: sp.Vec3
    hi: sp.Vec3


class CollisionWorld:
    """Collision geometry of a Scene, built once."""

    def __init__(self, scene: Scene) -> None:
        self._part_models = {body.name: _bvh(body) for body in scene.parts}
        self._fixed: list[_Fixed] = []
        for body in scene.environment:
            pose = body.initial_pose
            world = np.array([pose.apply(tuple(v)) for v in body.vertices])
            obj = fcl.CollisionObject(_bvh(body), _transform(pose))
            self._fixed.append(_Fixed(body.name, obj, tuple(world.min(axis=0)),
                                      tuple(world.max(axis=0))))
        self.stats = {"bounding_tests": 0, "fcl_distance_queries": 0}

    def environment_near(self, center: sp.Vec3, radius: float) -> tuple[int, ...]:
        """Indices of environment objects whose world box a sphere can touch."""
        self.stats["bounding_tests"] += 1
        near = []
        for index, fixed in enumerate(self._fixed):
            gap = 0.0
            for axis in range(3):
                c = center[axis]
                if c < fixed.lo[axis]:
                    gap += (fixed.lo[axis] - c) ** 2
                elif c > fixed.hi[axis]:
                    gap += (c - fixed.hi[axis]) ** 2
            if gap <= radius * radius:
                near.append(index)
        return tuple(near)

    def environment_name(self, index: int) -> str:
        return self._fixed[index].name

    def distance_to_environment(self, part: str, pose: sp.Pose,
                                candidates: tuple[int, ...]) -> tuple[float, int]:
        """Smallest distance from the posed part to the candidates (<= 0 when touching)."""
        obj = fcl.CollisionObject(self._part_models[part], _transform(pose))
        best, which = float("inf"), -1
        for index in candidates:
            self.stats["fcl_distance_queries"] += 1
            result = fcl.DistanceResult()
            d = fcl.distance(obj, self._fixed[index].obj, fcl.DistanceRequest(), result)
            if d < best:
                best, which = d, index
        return best, which
