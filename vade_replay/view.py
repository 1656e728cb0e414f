"""Rerun review of a session: one .rrd file that opens laid out for reviewing a run.

The only module that imports rerun (a layering test holds this). It consumes the
``FrameRecord`` stream that the simulator, the recording reader and replay all produce, so
a review can be written straight from a simulation, a recording or a replay, one frame at
a time: only the current flight or slide of each part is kept in memory.

Entity layout (``L`` is the run's label, e.g. ``recorded``; a compared run uses its own):

- ``world/environment/<name>``: fixed meshes, static.
- ``world/L/parts/<part>``, ``world/L/base``: a static mesh, then one Transform3D per frame.
- ``world/L/devices/<device>``: hands, head and tools as small axis frames.
- ``world/L/trajectories/<part>/<n>``: one line strip per flight (INSPACE) or slide
  (ONBASESLIDE), through the world centre of mass.
- ``states/L/<part>``: StateChange, logged at a part's first frame and when its mode changes.
- ``state_diagram``: the seven modes as a graph, the transitions used so far with counts,
  the modes the parts are in highlighted; re-logged when any mode changes.
- ``plots/{speed,angular_speed}/L/<part>``, ``plots/energy/L/<part>/{kinetic,potential,total}``.
- ``plots/difference/{position_m,rotation_rad}/<part>``: pose difference between two runs.
- ``events/L``: every event as a TextLog line with its cause.
- ``markers/divergence``: ERROR log and a state lane at the first diverging frame (a
  what-if's departure: an INFO line and a WHAT-IF DEPARTS lane).
"""

from __future__ import annotations

import itertools
import math
import os
import socket
import stat
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from vade_replay.errors import ConfigError
from vade_replay.recording import in_place
from vade_replay.tables import forget_temp, temp_beside
from vade_replay.frames import FrameRecord, PartSnapshot
from vade_replay import spatial as sp

MODES: tuple[str, ...] = ("INHAND", "ONTOOL", "ONBASESLIDE", "ONBASESTATIC", "INSPACE", "STATIC", "PLACED")
TRAJECTORY_MODES: frozenset[str] = frozenset({"INSPACE", "ONBASESLIDE"})

_MODE_COLORS: dict[str, int] = {
    "INHAND": 0x4C9BE8FF,
    "ONTOOL": 0x9B6FE0FF,
    "ONBASESLIDE": 0xE8A33DFF,
    "ONBASESTATIC": 0xC7B24AFF,
    "INSPACE": 0xE8603DFF,
    "STATIC": 0x8A8A8AFF,
    "PLACED": 0x4CB86AFF,
}
_IDLE_NODE_COLOR = 0x5A5A5AFF
_PART_COLORS: tuple[int, ...] = (
    0x3D9BE8FF, 0xE8B23DFF, 0x4CB86AFF, 0xD95FA0FF, 0x7E6FE0FF, 0x3DC8C8FF, 0xE8703DFF, 0xA0A03DFF,
)
_DEVICE_AXIS_M: dict[str, float] = {"right_hand": 0.08, "left_hand": 0.08, "head": 0.12}
_TOOL_AXIS_M = 0.05
_WARN_EVENTS = frozenset({"GrabRefused", "PartBlocked", "PartSlidOff"})
# Long flights and slides re-log their strip about this many times, not once per frame.
_STRIP_UPDATES = 64


@dataclass(frozen=True)
class MeshInfo:
    """Geometry and mass properties of one rigid object, in its own frame, metres and kg."""

    name: str
    vertices: np.ndarray  # (N, 3) float64
    faces: np.ndarray  # (M, 3) int
    mass_kg: float = 0.0
    center_of_mass: tuple = (0.0, 0.0, 0.0)  # in the object's frame
    inertia_cm: tuple = ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))  # at CM, object's axes
    color: tuple | None = None  # (r, g, b) or (r, g, b, a), 0-255, from the session


@dataclass(frozen=True)
class SceneInfo:
    """What a review needs of a scene: meshes of parts, base and environment, and gravity."""

    parts: tuple[MeshInfo, ...]  # names match PartSnapshot.name
    base: MeshInfo | None  # pose per frame is FrameRecord.base
    environment: tuple[tuple[MeshInfo, tuple, tuple], ...] = ()  # (mesh, position, rotation_xyzw)
    gravity: tuple = (0.0, 0.0, -9.8)  # world gravity, m/s^2, unscaled (the physics default)
    # The gravity a part moves under in a mode where it is scaled (``physics``'s
    # ``gravity_scale_free`` in INSPACE, ``gravity_scale_slide`` in ONBASESLIDE), so that
    # the energy plot's total is conserved where the physics conserves it (a researcher's
    # trial: with full g a free flight at 0.25 g gained 26 % up to its apex).
    gravity_by_mode: tuple[tuple[str, tuple], ...] = ()


def write_review(
    path: str | Path,
    *,
    scene: SceneInfo,
    frames: Iterable[FrameRecord],
    compare_frames: Iterable[FrameRecord] | None = None,
    compare_label: str = "replayed",
    label: str = "recorded",
    divergence_frame: int | None = None,
    application_id: str = "vade_replay",
    spawn: bool = False,
) -> dict:
    """Write a rerun review of a session to ``path`` (.rrd) and return counts of what was logged.

    ``frames`` is consumed once, in order, and may be long. With ``compare_frames`` (a second
    run of the same inputs, e.g. a replay or a what-if with changed physics) both runs are
    shown in one view, the second as translucent ghosts under ``compare_label``, and the
    pose difference per part is plotted; the two are iterated in lockstep and must carry the
    same frame numbers. ``divergence_frame`` is marked with an ERROR log line and a marker
    lane; ghosts of the compared run then appear from that frame on. ``spawn`` also streams
    to a freshly spawned native viewer.

    Returns a dict with ``frames``, ``transforms``, ``state_changes``, ``edges`` (distinct
    transitions used by the main run), ``events``, ``trajectories`` and ``compared_frames``.
    """
    if compare_frames is not None and compare_label == label:
        raise ValueError(f"compare_label and label must differ, both are {label!r}")
    has_compare = compare_frames is not None
    rec = rr.RecordingStream(application_id)
    # Wall-clock timelines would make two reviews of one session differ for no reason.
    rec.set_log_time_enabled(False)
    rec.set_log_tick_enabled(False)
    # Written beside its path and moved there when whole, as the tables are (a user's trial:
    # a full disk left a review cut short at its path, over the one there before).
    target = Path(path).resolve()
    try:
        pipe = stat.S_ISFIFO(os.stat(target).st_mode)
    except OSError:
        pipe = False
    if pipe:
        # (Opened, a named pipe with no reader blocks for ever in the open: a review.)
        raise ConfigError("cannot write a review to a named pipe: give a file", file=str(path))
    staged = target
    if not in_place(target):
        try:
            fd, name = temp_beside(target)
        except OSError as exc:
            raise _unwritable(exc, Path(path)) from None
        os.close(fd)
        staged = Path(name)
    try:
        try:
            if spawn:
                rec.spawn(connect=False)
                rec.set_sinks(rr.GrpcSink(), rr.FileSink(str(staged)))
            else:
                rec.save(str(staged))
        except (RuntimeError, OSError) as exc:
            raise _unwritable(exc, Path(path)) from None
        counts = _write_runs(rec, scene, frames, compare_frames, label, compare_label,
                             divergence_frame, has_compare, Path(path))
        if staged != target:
            os.replace(staged, target)
    finally:
        if staged != target:
            staged.unlink(missing_ok=True)
            forget_temp(str(staged))
    return counts


def _unwritable(exc: BaseException, path: Path) -> ConfigError:
    return ConfigError(f"cannot write the review here ({str(exc).splitlines()[0]})",
                       file=str(path))


# How long a flush of the review may wait for rerun's file writer: where the writer died (a
# full disk), rerun's flush waited for ever (a review of this change: 5 runs in 6 hung).
_FLUSH_TIMEOUT_S = 30.0


def _write_runs(rec: rr.RecordingStream, scene: SceneInfo, frames: Iterable[FrameRecord],
                compare_frames: Iterable[FrameRecord] | None, label: str, compare_label: str,
                divergence_frame: int | None, has_compare: bool, shown: Path) -> dict:
    """``write_review``'s logging, into ``rec`` with its sinks set; the file whole when it
    returns (``shown``: its path as given, for an error)."""
    blueprint = blueprint_from_runs(with_comparison=has_compare)

    def send_blueprint() -> None:
        # After the first frame is flushed, so the viewer knows the timeline the layout names.
        rec.flush(timeout_sec=_FLUSH_TIMEOUT_S)
        rec.send_blueprint(blueprint, make_active=True, make_default=True)

    try:
        _log_world_static(rec, scene=scene)
        counts = _log_runs(
            rec,
            scene=scene,
            frames=frames,
            compare_frames=compare_frames,
            label=label,
            compare_label=compare_label,
            divergence_frame=divergence_frame,
            on_first_frame=send_blueprint,
        )
        rec.flush(timeout_sec=_FLUSH_TIMEOUT_S)
    except RuntimeError as exc:
        # (rerun's writer stopping: a full disk, "File-writer thread shut down prematurely".)
        raise _unwritable(exc, shown) from None
    finally:
        try:
            rec.disconnect()
        except RuntimeError as exc:
            raise _unwritable(exc, shown) from None
    return counts


def blueprint_from_runs(*, with_comparison: bool) -> rrb.Blueprint:
    """The review's layout: scene, state lanes and events left; state diagram and plots right."""
    plots = [
        rrb.TimeSeriesView(origin="plots/speed", name="Speed (m/s)"),
        rrb.TimeSeriesView(origin="plots/angular_speed", name="Angular speed (rad/s)"),
        rrb.TimeSeriesView(origin="plots/energy", name="Energy KE+PE (J)"),
    ]
    if with_comparison:
        plots += [
            rrb.TimeSeriesView(origin="plots/difference/position_m", name="Position difference (m)"),
            rrb.TimeSeriesView(origin="plots/difference/rotation_rad", name="Rotation difference (rad)"),
        ]
    # Fixed node positions: the forces would otherwise shuffle the diagram on every re-log.
    no_forces = dict(
        force_link=rrb.archetypes.ForceLink(enabled=False),
        force_many_body=rrb.archetypes.ForceManyBody(enabled=False),
        force_position=rrb.archetypes.ForcePosition(enabled=False),
        force_collision_radius=rrb.archetypes.ForceCollisionRadius(enabled=False),
        force_center=rrb.archetypes.ForceCenter(enabled=False),
    )
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Vertical(
                rrb.Spatial3DView(origin="world", name="Scene"),
                rrb.StateTimelineView(origin="/", contents=["states/**", "markers/**"], name="Part states"),
                rrb.TextLogView(origin="/", contents=["events/**", "markers/**"], name="Events"),
                row_shares=[3, 1.2, 1.2],
            ),
            rrb.Vertical(
                rrb.GraphView(
                    origin="state_diagram",
                    name="State diagram",
                    visual_bounds=rrb.VisualBounds2D(x_range=[-320, 320], y_range=[-270, 270]),
                    **no_forces,
                ),
                rrb.Tabs(*plots, active_tab=0),
                row_shares=[1, 1],
            ),
            column_shares=[3, 2],
        ),
        rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
        # Opens on the last frame: whole state lanes, all transitions counted; scrub back from there.
        rrb.TimePanel(state="collapsed", timeline="frame", play_state="following"),
    )


def _log_runs(
    rec: rr.RecordingStream,
    *,
    scene: SceneInfo,
    frames: Iterable[FrameRecord],
    compare_frames: Iterable[FrameRecord] | None,
    label: str,
    compare_label: str,
    divergence_frame: int | None,
    on_first_frame: Callable[[], None],
) -> dict:
    main = _RunLogger(rec, scene=scene, label=label, ghost=False)
    other = None
    if compare_frames is not None:
        other = _RunLogger(rec, scene=scene, label=compare_label, ghost=True)
    diagram = _StateDiagram(rec)
    counts = {"frames": 0, "compared_frames": 0}
    marked = started = False
    for record, compared in _lockstep(frames, compare_frames):
        current = record if record is not None else compared
        rec.set_time("frame", sequence=current.frame)
        rec.set_time("sim_time", duration=np.timedelta64(current.time_ns, "ns"))
        if record is not None:
            counts["frames"] += 1
            if main.log_frame(record):
                diagram.log(modes=main.modes(), transitions=main.transitions)
        if compared is not None and other is not None:
            counts["compared_frames"] += 1
            # The ghosts appear where the runs part ways, or from the start for a what-if.
            if divergence_frame is None or compared.frame >= divergence_frame:
                other.log_frame(compared)
            if record is not None:
                _log_pose_difference(rec, record=record, compared=compared)
        if divergence_frame is not None and not marked and current.frame >= divergence_frame:
            _log_divergence(rec, frame=divergence_frame, record=record, compared=compared,
                            what_if=compare_label == "what_if")
            marked = True
        if not started:
            on_first_frame()
            started = True
    if not started:
        on_first_frame()
    main.finish()
    if other is not None:
        other.finish()
    counts.update(main.counts)
    counts["edges"] = len(main.transitions)
    return counts


def _lockstep(
    frames: Iterable[FrameRecord], compare_frames: Iterable[FrameRecord] | None
) -> Iterator[tuple[FrameRecord | None, FrameRecord | None]]:
    """Pairs of (frame, compared frame); a run that ends early leaves ``None`` on its side."""
    if compare_frames is None:
        for record in frames:
            yield record, None
        return
    for record, compared in itertools.zip_longest(frames, compare_frames):
        if record is not None and compared is not None and record.frame != compared.frame:
            raise ValueError(
                f"runs are not in lockstep: frame {record.frame} paired with frame {compared.frame}"
            )
        yield record, compared


class _RunLogger:
    """Logs one run's frames under its label; keeps only the open trajectory of each part."""

    def __init__(
        self, rec: rr.RecordingStream, *, scene: SceneInfo, label: str, ghost: bool
    ) -> None:
        self.rec = rec
        self.label = rr.escape_entity_path_part(label)
        self.ghost = ghost
        self.meshes = {mesh.name: mesh for mesh in scene.parts}
        self.base_mesh = scene.base
        self.gravity = tuple(float(g) for g in scene.gravity)
        self.gravity_by_mode = {mode: tuple(float(g) for g in gravity)
                                for mode, gravity in scene.gravity_by_mode}
        self.colors = {mesh.name: _rgba(mesh.color) if mesh.color else _PART_COLORS[i % len(_PART_COLORS)]
                       for i, mesh in enumerate(scene.parts)}
        self.mode_by_part: dict[str, str] = {}
        self.transitions: dict[tuple[str, str], int] = {}
        self.trajectory_index: dict[str, int] = {}
        self.open_strips: dict[str, list[tuple[float, float, float]]] = {}
        self._strip_mode: dict[str, str] = {}
        self.grip_by_device: dict[str, bool | None] = {}
        self.meshes_logged = False
        self.counts = {"transforms": 0, "state_changes": 0, "events": 0, "trajectories": 0}

    def modes(self) -> dict[str, str]:
        return dict(self.mode_by_part)

    def log_frame(self, record: FrameRecord) -> bool:
        """Log one frame; return whether any part's mode changed (or appeared)."""
        if not self.meshes_logged:
            self._log_meshes()
            self.meshes_logged = True
        world = f"world/{self.label}"
        changed = False
        for part in record.parts:
            path = f"{world}/parts/{rr.escape_entity_path_part(part.name)}"
            self._log_pose(path, part.position, part.rotation_xyzw)
            changed |= self._log_mode(part)
            self._extend_trajectory(part)
            self._log_scalars(part)
        if record.base is not None:
            self._log_pose(f"{world}/base", record.base.position, record.base.rotation_xyzw)
        if not self.ghost:
            self._log_devices(record)
        for event in record.events:
            self._log_event(event)
        return changed

    def finish(self) -> None:
        """Log the last state of every open trajectory."""
        for name in sorted(self.open_strips):
            self._close_trajectory(name)

    def _log_meshes(self) -> None:
        world = f"world/{self.label}"
        alpha = 0x60  # ghosts are see-through, never more opaque than the part itself
        for mesh in self.meshes.values():
            own = self.colors[mesh.name]
            color = own if not self.ghost else (own & 0xFFFFFF00) | min(own & 0xFF, alpha)
            path = f"{world}/parts/{rr.escape_entity_path_part(mesh.name)}"
            # Ghost meshes appear at the frame they start; the main run's never change.
            self.rec.log(path, _mesh3d_from_info(mesh, color=color), static=not self.ghost)
        if self.base_mesh is not None:
            base_rgba = _rgba(self.base_mesh.color) if self.base_mesh.color else 0x9C8A70FF
            color = base_rgba if not self.ghost else \
                (base_rgba & 0xFFFFFF00) | min(base_rgba & 0xFF, 0x60)
            self.rec.log(f"{world}/base", _mesh3d_from_info(self.base_mesh, color=color), static=not self.ghost)

    def _log_pose(self, path: str, position: tuple, rotation_xyzw: tuple) -> None:
        self.rec.log(path, rr.Transform3D(translation=position, quaternion=rr.Quaternion(xyzw=rotation_xyzw)))
        self.counts["transforms"] += 1

    def _log_mode(self, part: PartSnapshot) -> bool:
        previous = self.mode_by_part.get(part.name)
        if previous == part.mode:
            return False
        path = f"states/{self.label}/{rr.escape_entity_path_part(part.name)}"
        if previous is None:
            self.rec.log(path, _STATE_CONFIGURATION, static=True)
        else:
            key = (previous, part.mode)
            self.transitions[key] = self.transitions.get(key, 0) + 1
        self.rec.log(path, rr.StateChange(state=part.mode))
        self.counts["state_changes"] += 1
        self.mode_by_part[part.name] = part.mode
        return True

    def _extend_trajectory(self, part: PartSnapshot) -> None:
        strip = self.open_strips.get(part.name)
        in_motion = part.mode in TRAJECTORY_MODES
        # A flight or slide ends when the mode changes, also from INSPACE straight to a slide.
        if strip is not None and (not in_motion or part.mode != self._strip_mode[part.name]):
            self._close_trajectory(part.name)
            strip = None
        if not in_motion:
            return
        if strip is None:
            strip = self.open_strips[part.name] = []
            self._strip_mode[part.name] = part.mode
            self.trajectory_index[part.name] = self.trajectory_index.get(part.name, -1) + 1
            self.counts["trajectories"] += 1
        strip.append(_world_cm(part, self.meshes.get(part.name)))
        n = len(strip)
        if n % max(1, n // _STRIP_UPDATES) == 0:
            self._log_strip(part.name)

    def _close_trajectory(self, name: str) -> None:
        self._log_strip(name)
        del self.open_strips[name]

    def _log_strip(self, name: str) -> None:
        strip = self.open_strips[name]
        mode = self._strip_mode[name]
        path = (
            f"world/{self.label}/trajectories/{rr.escape_entity_path_part(name)}/{self.trajectory_index[name]}"
        )
        color = _MODE_COLORS[mode] if not self.ghost else (_MODE_COLORS[mode] & 0xFFFFFF00) | 0x80
        self.rec.log(path, rr.LineStrips3D([strip], colors=[color], radii=[0.002]))

    def _log_scalars(self, part: PartSnapshot) -> None:
        mesh = self.meshes.get(part.name)
        name = rr.escape_entity_path_part(part.name)
        self.rec.log(f"plots/speed/{self.label}/{name}", rr.Scalars(_norm(part.linear_velocity)))
        self.rec.log(f"plots/angular_speed/{self.label}/{name}", rr.Scalars(_norm(part.angular_velocity)))
        if mesh is None:
            return
        kinetic, potential = energy_from_snapshot(
            part, mesh=mesh, gravity=self.gravity_by_mode.get(part.mode, self.gravity))
        energy = f"plots/energy/{self.label}/{name}"
        self.rec.log(f"{energy}/kinetic", rr.Scalars(kinetic))
        self.rec.log(f"{energy}/potential", rr.Scalars(potential))
        self.rec.log(f"{energy}/total", rr.Scalars(kinetic + potential))

    def _log_devices(self, record: FrameRecord) -> None:
        for name, sample in record.inputs.devices:
            path = f"world/{self.label}/devices/{rr.escape_entity_path_part(name)}"
            if name not in self.grip_by_device:
                axis_m = _DEVICE_AXIS_M.get(name, _TOOL_AXIS_M)
                self.rec.log(path, rr.TransformAxes3D(axis_m), static=True)
            if name not in self.grip_by_device or self.grip_by_device[name] != sample.grip:
                # The marker shows the grip: green while closed, grey while open or no glove.
                color = 0x4CB86AFF if sample.grip else 0xBBBBBBFF
                self.rec.log(path, rr.Points3D([[0.0, 0.0, 0.0]], colors=[color], radii=[0.012], labels=[name]))
                self.grip_by_device[name] = sample.grip
            self._log_pose(path, sample.position, sample.rotation_xyzw)

    def _log_event(self, event: object) -> None:
        kind = getattr(event, "kind", type(event).__name__)
        describe = getattr(event, "describe", None)
        text = describe() if callable(describe) else repr(event)
        cause = getattr(event, "cause", "")
        if cause and cause not in text:
            text = f"{text} (cause: {cause})"
        level = rr.TextLogLevel.WARN if kind in _WARN_EVENTS else rr.TextLogLevel.INFO
        self.rec.log(f"events/{self.label}", rr.TextLog(f"[{kind}] {text}", level=level))
        self.counts["events"] += 1


class _StateDiagram:
    """The seven modes on a circle, the transitions used so far, the occupied modes lit."""

    # Around the circle in this order, the common transitions join neighbours.
    CIRCLE = ("INHAND", "ONTOOL", "PLACED", "ONBASESTATIC", "ONBASESLIDE", "STATIC", "INSPACE")

    def __init__(self, rec: rr.RecordingStream) -> None:
        self.rec = rec
        n = len(self.CIRCLE)
        self.positions = {
            mode: (220.0 * math.cos(angle), 220.0 * math.sin(angle))
            for i, mode in enumerate(self.CIRCLE)
            for angle in (2 * math.pi * i / n - math.pi / 2,)
        }

    def log(self, *, modes: dict[str, str], transitions: dict[tuple[str, str], int]) -> None:
        parts_by_mode: dict[str, list[str]] = {}
        for part, mode in sorted(modes.items()):
            parts_by_mode.setdefault(mode, []).append(part)
        ids, labels, colors, positions, radii = [], [], [], [], []
        for mode in MODES:
            held = parts_by_mode.get(mode, [])
            ids.append(mode)
            labels.append(f"{mode}: {', '.join(held)}" if held else mode)
            colors.append(_MODE_COLORS[mode] if held else _IDLE_NODE_COLOR)
            positions.append(self.positions[mode])
            radii.append(14.0 if held else 8.0)
        # GraphEdges carry no labels: a small node beside each edge's middle holds the count.
        for (src, dst), count in sorted(transitions.items()):
            (x0, y0), (x1, y1) = self.positions.get(src, (0, 0)), self.positions.get(dst, (0, 0))
            dx, dy = x1 - x0, y1 - y0
            length = math.hypot(dx, dy) or 1.0
            # Left of the direction of travel, so A->B and B->A labels do not overlap.
            ids.append(f"{src}->{dst}")
            labels.append(f"×{count}")
            colors.append(0x606060FF)
            positions.append((x0 + dx / 2 - 18.0 * dy / length, y0 + dy / 2 + 18.0 * dx / length))
            radii.append(2.0)
        self.rec.log(
            "state_diagram",
            rr.GraphNodes(ids, labels=labels, colors=colors, positions=positions, radii=radii, show_labels=True),
            rr.GraphEdges(sorted(transitions) or [], graph_type="directed"),
        )


def energy_from_snapshot(part: PartSnapshot, *, mesh: MeshInfo, gravity: tuple) -> tuple[float, float]:
    """Kinetic and potential energy (J) of a part: 0.5 m v^2 + 0.5 w.I_world.w and -m g.x_cm.

    ``linear_velocity`` is the CM velocity and ``angular_velocity`` is in world axes, as in
    ``PartSnapshot``; I_world = R I_cm R^T, so w.I_world.w = (R^T w).I_cm.(R^T w).
    """
    world_from_part = _matrix_from_quat(part.rotation_xyzw)
    w_part = world_from_part.T @ np.asarray(part.angular_velocity, dtype=np.float64)
    inertia = np.asarray(mesh.inertia_cm, dtype=np.float64)
    v = part.linear_velocity
    kinetic = 0.5 * mesh.mass_kg * (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]) + 0.5 * float(w_part @ inertia @ w_part)
    cm = _world_cm(part, mesh)
    potential = -mesh.mass_kg * (gravity[0] * cm[0] + gravity[1] * cm[1] + gravity[2] * cm[2])
    return kinetic, potential


def _log_pose_difference(rec: rr.RecordingStream, *, record: FrameRecord, compared: FrameRecord) -> None:
    others = {part.name: part for part in compared.parts}
    for part in record.parts:
        other = others.get(part.name)
        if other is None:
            continue
        name = rr.escape_entity_path_part(part.name)
        distance_m = math.dist(part.position, other.position)
        rec.log(f"plots/difference/position_m/{name}", rr.Scalars(distance_m))
        angle_rad = sp.quat_angle_between(part.rotation_xyzw, other.rotation_xyzw)
        rec.log(f"plots/difference/rotation_rad/{name}", rr.Scalars(angle_rad))


def _log_divergence(
    rec: rr.RecordingStream, *, frame: int, record: FrameRecord | None, compared: FrameRecord | None,
    what_if: bool = False,
) -> None:
    # Logged at the divergence frame itself, even if the stream skipped it. A what-if's
    # departure is what it was asked for: marked as such, not as an error (a researcher's
    # trial read the red DIVERGED lane and ERROR line of a what-if as a failure).
    rec.set_time("frame", sequence=frame)
    state, color, level = ("WHAT-IF DEPARTS", 0xE0A040FF, rr.TextLogLevel.INFO) if what_if \
        else ("DIVERGED", 0xE04040FF, rr.TextLogLevel.ERROR)
    verb = "departs" if what_if else "diverges"
    text = (f"The what-if departs from the recording at frame {frame}" if what_if
            else f"Runs diverge at frame {frame}")
    differing = list(record.parts) if record is not None else []
    if record is not None and compared is not None:
        others = {part.name: part for part in compared.parts}
        differing = [part for part in record.parts if others.get(part.name) != part]
        if differing:
            text += f": {', '.join(part.name for part in differing)}"
    rec.log("markers/divergence", rr.TextLog(text, level=level), rr.StateChange(state=state))
    rec.log("markers/divergence", rr.StateConfiguration(values=[state], colors=[color]), static=True)
    if differing:
        rec.log(
            "world/markers/divergence",
            rr.Points3D(
                [part.position for part in differing],
                colors=[color],
                radii=[0.015],
                labels=[f"{part.name} {verb} @ {frame}" for part in differing],
            ),
        )


def _log_world_static(rec: rr.RecordingStream, *, scene: SceneInfo) -> None:
    rec.log("world", _view_coordinates_from_gravity(scene.gravity), static=True)
    for mesh, position, rotation_xyzw in scene.environment:
        path = f"world/environment/{rr.escape_entity_path_part(mesh.name)}"
        rec.log(path, _mesh3d_from_info(mesh, color=_rgba(mesh.color) if mesh.color else 0xB0B0B8FF),
                static=True)
        rec.log(path, rr.Transform3D(translation=position, quaternion=rr.Quaternion(xyzw=rotation_xyzw)), static=True)


def _view_coordinates_from_gravity(gravity: tuple) -> rr.ViewCoordinates:
    """Up is against gravity, along its largest axis (VADE scenes are Y-up, others may not be)."""
    axis = max(range(3), key=lambda i: abs(gravity[i]))
    up_is_positive = gravity[axis] <= 0.0
    table = {
        (0, True): rr.ViewCoordinates.RIGHT_HAND_X_UP,
        (0, False): rr.ViewCoordinates.RIGHT_HAND_X_DOWN,
        (1, True): rr.ViewCoordinates.RIGHT_HAND_Y_UP,
        (1, False): rr.ViewCoordinates.RIGHT_HAND_Y_DOWN,
        (2, True): rr.ViewCoordinates.RIGHT_HAND_Z_UP,
        (2, False): rr.ViewCoordinates.RIGHT_HAND_Z_DOWN,
    }
    return table[(axis, up_is_positive)]


def _rgba(color: tuple) -> int:
    """A session's (r, g, b[, a]) colour as rerun's 0xRRGGBBAA."""
    r, g, b = (int(c) & 0xFF for c in color[:3])
    a = int(color[3]) & 0xFF if len(color) > 3 else 0xFF
    return (r << 24) | (g << 16) | (b << 8) | a


def _mesh3d_from_info(mesh: MeshInfo, *, color: int) -> rr.Mesh3D:
    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    faces = np.asarray(mesh.faces, dtype=np.int64)
    return rr.Mesh3D(
        vertex_positions=vertices,
        triangle_indices=faces.astype(np.uint32),
        vertex_normals=_vertex_normals(vertices, faces),
        albedo_factor=color,
    )


def _vertex_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    # Area-weighted face normals summed per vertex: smooth shading without trimesh here.
    tri = vertices[faces]
    face_normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    normals = np.zeros_like(vertices)
    for k in range(3):
        np.add.at(normals, faces[:, k], face_normals)
    lengths = np.linalg.norm(normals, axis=1, keepdims=True)
    return np.divide(normals, lengths, out=np.zeros_like(normals), where=lengths > 0)


def _world_cm(part: PartSnapshot, mesh: MeshInfo | None) -> tuple[float, float, float]:
    if mesh is None:
        return tuple(float(x) for x in part.position)
    offset = _matrix_from_quat(part.rotation_xyzw) @ np.asarray(mesh.center_of_mass, dtype=np.float64)
    x, y, z = part.position
    return (x + float(offset[0]), y + float(offset[1]), z + float(offset[2]))


def _matrix_from_quat(q: tuple) -> np.ndarray:
    x, y, z, w = q
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def _norm(v: tuple) -> float:
    return math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])


_STATE_CONFIGURATION = rr.StateConfiguration(values=list(MODES), colors=[_MODE_COLORS[m] for m in MODES])


def serve_web_viewer_assets(*, port: int = 0) -> str:
    """Serve rerun's bundled web viewer over HTTP in this process; return its base URL.

    Only the viewer's page and wasm: a recording is passed to it as ``?url=``. Lives here
    because this is the one module that imports rerun. ``port=0`` picks a free port.
    """
    if port == 0:
        # rerun picks a random port itself but does not say which: pick one we can name.
        with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
            probe.bind(("127.0.0.1", 0))
            port = probe.getsockname()[1]
    rr.start_web_viewer_server(port)
    return f"http://127.0.0.1:{port}"
