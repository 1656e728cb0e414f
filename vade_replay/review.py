"""The rerun review of a recording: recorded run, and the replay or what-if beside it.

This joins the replay (which knows scenes and recordings) to the view (which knows rerun and
only the plain frame records), so neither has to know the other.
"""

from __future__ import annotations

from pathlib import Path
from typing import Iterator

from .frames import FrameRecord
from .recording import Recording
from .replay import apply_overrides, as_made, recorded_records, simulate
from .scene import Body, Scene
from .view import MeshInfo, SceneInfo, write_review


def _mesh(body: Body) -> MeshInfo:
    return MeshInfo(body.name, body.vertices, body.faces, body.mass_kg, body.center_of_mass,
                    body.inertia_cm, body.color)


def scene_info(scene: Scene) -> SceneInfo:
    """What the review needs of a scene: meshes, mass properties, gravity."""
    return SceneInfo(
        parts=tuple(_mesh(b) for b in scene.parts),
        base=_mesh(scene.base) if scene.base else None,
        environment=tuple((_mesh(b), b.initial_pose.position, b.initial_pose.rotation)
                          for b in scene.environment),
        gravity=scene.physics.gravity,
        gravity_by_mode=(("INSPACE", scene.physics.gravity_free),
                         ("ONBASESLIDE", scene.physics.gravity_slide)))


def _recorded(recording: Recording) -> Iterator[FrameRecord]:
    yield from recorded_records(recording)


def write_recording_review(recording: Recording, out: str | Path, *,
                           overrides: dict[str, str] | None = None,
                           divergence_frame: int | None = None, spawn: bool = False,
                           as_recorded: bool = False) -> dict:
    """Write ``out`` (.rrd): the recorded run, plus the re-run where it matters.

    With ``overrides`` (a what-if), the changed run is shown beside the recorded one from
    the start, with the pose difference over time. Without them, the replay is shown beside
    the recording only if it diverged, from ``divergence_frame`` on. With ``as_recorded``
    the re-run has the physics defaults the recording was made with (``replay.as_made``).
    """
    session = as_made(recording)[0] if as_recorded else recording.session
    base_scene = session.build_scene()
    session, applied = apply_overrides(session, overrides or {})
    scene = session.build_scene() if applied else base_scene
    compare = None
    label = "replayed"
    if applied:
        label = "what_if"  # an entity path segment; the changes are in the replay summary
    if applied or divergence_frame is not None:
        compare = simulate(scene, (f.inputs for f in recording.frames()))
    return write_review(Path(out), scene=scene_info(base_scene), frames=_recorded(recording),
                        compare_frames=compare, label="recorded", compare_label=label,
                        divergence_frame=divergence_frame, spawn=spawn)
