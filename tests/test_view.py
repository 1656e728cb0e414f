"""The rerun review: write synthetic sessions, read the .rrd back with rerun's own reader."""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass

import numpy as np
import pyarrow as pa
import pytest

rr = pytest.importorskip("rerun")
from rerun.chunk import RrdReader  # noqa: E402  (rerun 0.41's reader; rerun.dataframe is gone)

from vade_replay.frames import DeviceSample, FrameRecord, PartSnapshot, TrackerFrame  # noqa: E402
from vade_replay.view import MeshInfo, SceneInfo, energy_from_snapshot, write_review  # noqa: E402

DT_NS = 11_111_111  # 90 Hz
GRAVITY = (0.0, -9.81, 0.0)
N_FRAMES = 30
# Each part's mode by frame range: a hand-made session with flights, a slide and a placement.
PEG_MODES = [(0, "INHAND"), (5, "INSPACE"), (13, "STATIC"), (20, "INHAND"), (25, "INSPACE"), (28, "PLACED")]
BOLT_MODES = [(0, "STATIC"), (10, "ONBASESLIDE"), (16, "ONBASESTATIC")]


@dataclass(frozen=True)
class FakeEvent:
    kind: str
    frame: int
    part: str
    cause: str

    def describe(self) -> str:
        return f"{self.part}: {self.kind} at frame {self.frame}"


@dataclass(frozen=True)
class FakeModeChanged:
    frame: int
    part: str
    cause: str
    from_mode: str
    to_mode: str
    kind: str = "ModeChanged"
    # No describe(): the review falls back to repr.


def box_mesh(name: str, *, size_m: float, mass_kg: float) -> MeshInfo:
    h = size_m / 2
    vertices = np.array([[x, y, z] for x in (-h, h) for y in (-h, h) for z in (-h, h)], dtype=np.float64)
    faces = np.array(
        [[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
         [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]]
    )
    i = mass_kg * size_m * size_m / 6
    return MeshInfo(
        name=name, vertices=vertices, faces=faces, mass_kg=mass_kg,
        center_of_mass=(0.0, 0.01, 0.0), inertia_cm=((i, 0, 0), (0, 2 * i, 0), (0, 0, 3 * i)),
    )


SCENE = SceneInfo(
    parts=(box_mesh("bolt", size_m=0.03, mass_kg=0.05), box_mesh("peg", size_m=0.04, mass_kg=0.2)),
    base=box_mesh("base", size_m=0.2, mass_kg=1.0),
    environment=((box_mesh("table", size_m=1.0, mass_kg=0.0), (0.0, 0.3, 0.0), (0.0, 0.0, 0.0, 1.0)),),
    gravity=GRAVITY,
)


def mode_at(table: list[tuple[int, str]], frame: int) -> str:
    return [mode for start, mode in table if start <= frame][-1]


def expected_changes(table: list[tuple[int, str]]) -> list[tuple[int, str]]:
    return list(table)


def session(*, n_frames: int = N_FRAMES, nudge_from: int | None = None):
    """A generator of frames, so the review is fed as a stream; ``nudge_from`` shifts the peg."""
    for frame in range(n_frames):
        t = frame * DT_NS / 1e9
        offset = 0.01 * (frame - nudge_from + 1) if nudge_from is not None and frame >= nudge_from else 0.0
        angle = 0.1 * frame
        peg = PartSnapshot(
            name="peg", mode=mode_at(PEG_MODES, frame),
            position=(0.1 + offset, 1.0 + 0.01 * frame, 0.0),
            rotation_xyzw=(0.0, math.sin(angle / 2), 0.0, math.cos(angle / 2)),
            linear_velocity=(0.0, 0.9, 0.0), angular_velocity=(0.0, 9.0, 0.0),
        )
        bolt = PartSnapshot(
            name="bolt", mode=mode_at(BOLT_MODES, frame), position=(0.3, 0.9, 0.05 * t),
            rotation_xyzw=(0.0, 0.0, 0.0, 1.0), linear_velocity=(0.0, 0.0, 0.05), angular_velocity=(0.0, 0.0, 0.0),
        )
        base = PartSnapshot(
            name="base", mode="INHAND", position=(-0.2, 0.9, 0.0), rotation_xyzw=(0.0, 0.0, 0.0, 1.0),
            linear_velocity=(0.0, 0.0, 0.0), angular_velocity=(0.0, 0.0, 0.0),
        )
        devices = (
            ("head", DeviceSample((0.0, 1.6, 0.3), (0.0, 0.0, 0.0, 1.0))),
            ("left_hand", DeviceSample((-0.2, 0.9, 0.0), (0.0, 0.0, 0.0, 1.0), grip=True)),
            ("right_hand", DeviceSample((0.1, 1.0, 0.0), (0.0, 0.0, 0.0, 1.0), grip=frame < 5)),
        )
        events = []
        for name, table in (("bolt", BOLT_MODES), ("peg", PEG_MODES)):
            if frame > 0 and mode_at(table, frame) != mode_at(table, frame - 1):
                events.append(FakeModeChanged(frame, name, "test", mode_at(table, frame - 1), mode_at(table, frame)))
        if frame == 5:
            events.append(FakeEvent("PartReleased", frame, "peg", "grip opened"))
        if frame == 12:
            events.append(FakeEvent("PartBlocked", frame, "peg", "collision with table"))
        yield FrameRecord(
            inputs=TrackerFrame(frame=frame, time_ns=frame * DT_NS, devices=devices),
            base=base, parts=(bolt, peg), events=tuple(events),
        )


def read_rrd(path) -> dict[str, list]:
    """Entity path -> list of (is_static, {column name: python list}) for every chunk."""
    by_entity: dict[str, list] = {}
    for chunk in RrdReader(path).stream():
        batch = chunk.to_record_batch()
        columns = {}
        for name in batch.schema.names:
            column = batch.column(name)
            # Durations read as int nanoseconds: datetime.timedelta cannot hold them.
            if pa.types.is_duration(column.type):
                column = column.cast(pa.int64())
            columns[name] = column.to_pylist()
        by_entity.setdefault(chunk.entity_path, []).append((chunk.is_static, columns))
    return by_entity


def rows(store: dict, entity: str, column: str, *, static: bool = False, batch: bool = False) -> list[tuple]:
    """(frame, value) rows of one component column, sorted by frame; frame is None for static.

    A value is the row's first instance, or with ``batch`` the list of all its instances.
    """
    out = []
    for is_static, columns in store.get(entity, []):
        if is_static != static or column not in columns:
            continue
        frames = columns.get("frame", [None] * len(columns[column]))
        out += [(f, v if batch else v[0]) for f, v in zip(frames, columns[column]) if v]
    return sorted(out, key=lambda fv: -1 if fv[0] is None else fv[0])


@pytest.fixture(scope="module")
def single(tmp_path_factory):
    path = tmp_path_factory.mktemp("review") / "single.rrd"
    counts = write_review(path, scene=SCENE, frames=session())
    return path, counts, read_rrd(path)


def test_meshes_are_static_and_transforms_come_once_per_frame(single):
    path, counts, store = single
    for entity in ("/world/recorded/parts/peg", "/world/recorded/parts/bolt", "/world/recorded/base",
                   "/world/environment/table"):
        (_, vertices), = rows(store, entity, "Mesh3D:vertex_positions", static=True, batch=True)
        assert len(vertices) == 8, entity
    for entity in ("/world/recorded/parts/peg", "/world/recorded/parts/bolt", "/world/recorded/base",
                   "/world/recorded/devices/right_hand", "/world/recorded/devices/left_hand",
                   "/world/recorded/devices/head"):
        translations = rows(store, entity, "Transform3D:translation")
        assert [f for f, _ in translations] == list(range(N_FRAMES)), entity
    peg = rows(store, "/world/recorded/parts/peg", "Transform3D:translation")
    assert peg[7][1] == pytest.approx([0.1, 1.07, 0.0])
    assert counts["frames"] == N_FRAMES
    assert counts["transforms"] == N_FRAMES * 6  # two parts, base, three devices


def test_both_timelines_carry_frame_and_sim_time(single):
    _, _, store = single
    stamps = sorted(
        (frame, sim_time)
        for is_static, columns in store["/world/recorded/parts/peg"] if not is_static
        for frame, sim_time in zip(columns["frame"], columns["sim_time"])
    )
    assert stamps == [(f, f * DT_NS) for f in range(N_FRAMES)]


def test_state_lanes_hold_each_change_once(single):
    _, counts, store = single
    for name, table in (("peg", PEG_MODES), ("bolt", BOLT_MODES)):
        lane = rows(store, f"/states/recorded/{name}", "StateChange:state")
        assert lane == expected_changes(table), name
    assert counts["state_changes"] == len(PEG_MODES) + len(BOLT_MODES)
    (_, values), = rows(store, "/states/recorded/peg", "StateConfiguration:values", static=True, batch=True)
    assert set(values) == {"INHAND", "ONTOOL", "ONBASESLIDE", "ONBASESTATIC", "INSPACE", "STATIC", "PLACED"}


def test_state_diagram_has_used_transitions_with_counts(single):
    _, counts, store = single
    used = Counter()
    for table in (PEG_MODES, BOLT_MODES):
        used.update((a, b) for (_, a), (_, b) in zip(table, table[1:]))
    edges = rows(store, "/state_diagram", "GraphEdges:edges", batch=True)
    last_frame, last_edges = edges[-1]
    assert last_frame == 28  # the last mode change
    assert {(e["first"], e["second"]) for e in last_edges} == set(used)
    assert counts["edges"] == len(used) == 6
    nodes = dict(rows(store, "/state_diagram", "GraphNodes:node_ids", batch=True))
    labels = dict(rows(store, "/state_diagram", "GraphNodes:labels", batch=True))
    final = dict(zip(nodes[28], labels[28]))
    assert final["INHAND->INSPACE"] == "×2"
    assert final["PLACED"] == "PLACED: peg" and final["ONBASESTATIC"] == "ONBASESTATIC: bolt"
    # The diagram is re-logged at frame 0 and at each frame where a mode changes.
    assert list(nodes) == sorted({f for f, _ in PEG_MODES + BOLT_MODES})
    at_start = dict(zip(nodes[0], labels[0]))
    assert at_start["INHAND"] == "INHAND: peg" and at_start["INSPACE"] == "INSPACE"


def test_one_trajectory_strip_per_flight_or_slide(single):
    _, counts, store = single
    strips = sorted(e for e in store if e.startswith("/world/recorded/trajectories/"))
    assert strips == ["/world/recorded/trajectories/bolt/0", "/world/recorded/trajectories/peg/0",
                      "/world/recorded/trajectories/peg/1"]
    assert counts["trajectories"] == 3
    (_, first_flight) = rows(store, "/world/recorded/trajectories/peg/0", "LineStrips3D:strips", batch=True)[-1]
    assert len(first_flight[0]) == 13 - 5  # frames 5..12, through the world CM
    assert first_flight[0][0] == pytest.approx([0.1 + 0.01 * math.sin(0.25), 1.05, 0.0], abs=0.01)


def test_scalars_speed_and_energy(single):
    _, _, store = single
    speed = rows(store, "/plots/speed/recorded/peg", "Scalars:scalars")
    assert len(speed) == N_FRAMES and speed[0][1] == pytest.approx(0.9)
    assert rows(store, "/plots/angular_speed/recorded/peg", "Scalars:scalars")[3][1] == pytest.approx(9.0)
    total = rows(store, "/plots/energy/recorded/peg/total", "Scalars:scalars")
    frame = 7
    peg = next(p for p in list(session())[frame].parts if p.name == "peg")
    mesh = SCENE.parts[1]
    i_yy = 2 * mesh.inertia_cm[0][0]  # rotation about y keeps y: w.I_world.w = I_yy w^2
    cm_y = 1.0 + 0.01 * frame + 0.01
    expected = 0.5 * 0.2 * 0.81 + 0.5 * i_yy * 81.0 + 0.2 * 9.81 * cm_y
    assert total[frame][1] == pytest.approx(expected)
    assert sum(energy_from_snapshot(peg, mesh=mesh, gravity=GRAVITY)) == pytest.approx(expected)


def test_events_are_logged_with_cause(single):
    _, counts, store = single
    texts = rows(store, "/events/recorded", "TextLog:text")
    levels = dict(rows(store, "/events/recorded", "TextLog:level"))
    assert counts["events"] == len(texts) == 7 + 2
    blocked = [(f, t) for f, t in texts if "PartBlocked" in t]
    assert blocked == [(12, "[PartBlocked] peg: PartBlocked at frame 12 (cause: collision with table)")]
    assert levels[12] == "WARN"
    # An event without describe() still shows, through its repr.
    assert any("FakeModeChanged(" in t and "to_mode='PLACED'" in t for _, t in texts)


def test_blueprint_is_sent_with_the_recording(single):
    path, _, _ = single
    reader = RrdReader(path)
    (blueprint,) = reader.blueprints()
    classes = set()
    for chunk in reader.stream(store=blueprint):
        batch = chunk.to_record_batch()
        for name in batch.schema.names:
            if name.endswith(":class_identifier"):
                classes.update(v[0] for v in batch.column(name).to_pylist() if v)
    assert {"3D", "StateTimeline", "Graph", "TimeSeries", "TextLog"} <= classes


@pytest.fixture(scope="module")
def compared(tmp_path_factory):
    path = tmp_path_factory.mktemp("review") / "compared.rrd"
    counts = write_review(
        path, scene=SCENE, frames=session(), compare_frames=session(nudge_from=17), divergence_frame=17,
    )
    return path, counts, read_rrd(path)


def test_a_what_ifs_departure_is_marked_as_asked_for_not_as_an_error(tmp_path):
    """A researcher's trial read a what-if review's red DIVERGED lane and ERROR line as a
    failure: departing is what a what-if is for. It is an INFO line and an amber
    WHAT-IF DEPARTS lane; a replay's divergence stays an ERROR (above)."""
    path = tmp_path / "what_if.rrd"
    write_review(path, scene=SCENE, frames=session(), compare_frames=session(nudge_from=17),
                 compare_label="what_if", divergence_frame=17)
    store = read_rrd(path)
    ((frame, text),) = rows(store, "/markers/divergence", "TextLog:text")
    assert frame == 17 and text == "The what-if departs from the recording at frame 17: peg"
    assert rows(store, "/markers/divergence", "TextLog:level") == [(17, "INFO")]
    assert rows(store, "/markers/divergence", "StateChange:state") == [(17, "WHAT-IF DEPARTS")]


def test_divergence_is_marked_at_its_frame(compared):
    _, counts, store = compared
    ((frame, text),) = rows(store, "/markers/divergence", "TextLog:text")
    assert frame == 17 and text == "Runs diverge at frame 17: peg"
    assert rows(store, "/markers/divergence", "TextLog:level") == [(17, "ERROR")]
    assert rows(store, "/markers/divergence", "StateChange:state") == [(17, "DIVERGED")]
    assert [f for f, _ in rows(store, "/world/markers/divergence", "Points3D:positions")] == [17]
    assert counts["compared_frames"] == N_FRAMES


def test_compared_run_shows_as_ghosts_from_the_divergence(compared):
    _, _, store = compared
    ghost = rows(store, "/world/replayed/parts/peg", "Transform3D:translation")
    assert [f for f, _ in ghost] == list(range(17, N_FRAMES))
    assert ghost[0][1] == pytest.approx([0.11, 1.17, 0.0])
    (frame, _), = rows(store, "/world/replayed/parts/peg", "Mesh3D:vertex_positions")
    assert frame == 17
    assert len(rows(store, "/world/recorded/parts/peg", "Transform3D:translation")) == N_FRAMES


def test_pose_difference_is_plotted_per_part(compared):
    _, _, store = compared
    distance = rows(store, "/plots/difference/position_m/peg", "Scalars:scalars")
    assert [f for f, _ in distance] == list(range(N_FRAMES))
    assert all(v == 0.0 for f, v in distance if f < 17)
    assert distance[20][1] == pytest.approx(0.04)
    angle = rows(store, "/plots/difference/rotation_rad/bolt", "Scalars:scalars")
    assert all(v == 0.0 for _, v in angle)


def test_what_if_without_divergence_shows_both_runs_from_the_start(tmp_path):
    path = tmp_path / "what_if.rrd"
    write_review(path, scene=SCENE, frames=session(n_frames=6), compare_frames=session(n_frames=6, nudge_from=0),
                 compare_label="stiffer")
    store = read_rrd(path)
    assert [f for f, _ in rows(store, "/world/stiffer/parts/peg", "Transform3D:translation")] == list(range(6))
    assert rows(store, "/plots/difference/position_m/peg", "Scalars:scalars")[0][1] == pytest.approx(0.01)
    assert "/markers/divergence" not in store


def test_runs_out_of_lockstep_are_refused(tmp_path):
    shifted = (r for r in session(n_frames=4) if r.frame > 0)
    with pytest.raises(ValueError, match="lockstep"):
        write_review(tmp_path / "x.rrd", scene=SCENE, frames=session(n_frames=4), compare_frames=shifted)


def test_long_flights_relog_their_strip_a_bounded_number_of_times(tmp_path):
    def thrown(n_frames):
        for frame in range(n_frames):
            part = PartSnapshot("peg", "INSPACE", (0.001 * frame, 1.0, 0.0), (0.0, 0.0, 0.0, 1.0),
                                (0.09, 0.0, 0.0), (0.0, 0.0, 0.0))
            yield FrameRecord(inputs=TrackerFrame(frame=frame, time_ns=frame * DT_NS, devices=()),
                              base=None, parts=(part,))

    path = tmp_path / "long.rrd"
    write_review(path, scene=SCENE, frames=thrown(1000))
    strips = rows(read_rrd(path), "/world/recorded/trajectories/peg/0", "LineStrips3D:strips", batch=True)
    # Every frame up to 64 points, then sparser: about 64 * (1 + ln(n / 64)) updates, not n.
    assert 64 <= len(strips) <= 300
    # The last update holds the whole flight.
    assert len(strips[-1][1][0]) == 1000


def test_an_empty_session_still_writes_a_laid_out_file(tmp_path):
    path = tmp_path / "empty.rrd"
    counts = write_review(path, scene=SCENE, frames=iter(()))
    assert counts["frames"] == counts["transforms"] == counts["edges"] == 0
    reader = RrdReader(path)
    assert len(reader.blueprints()) == 1
    assert "/world/environment/table" in read_rrd(path)


def test_a_tool_is_reviewed_as_a_device_with_its_grip(tmp_path):
    """The hoist golden: the tool is drawn as a device frame following its tracker pose, its
    marker green from the frame it attaches the ring (48) to the frame it lets go (192), and
    the ring's state lane shows ONTOOL between."""
    from conftest import RECORDINGS, run_cli
    path = tmp_path / "hoist.rrd"
    result = run_cli("vade-replay", str(RECORDINGS / "hoist_placed.mcap"), "--rerun", str(path))
    assert result.returncode == 0, result.stderr
    store = read_rrd(path)
    hoist = "/world/recorded/devices/hoist"
    assert rows(store, hoist, "Points3D:colors") == [(0, 0xBBBBBBFF), (48, 0x4CB86AFF),
                                                     (192, 0xBBBBBBFF)]
    assert {v for _, v in rows(store, hoist, "Points3D:labels")} == {"hoist"}
    assert len(rows(store, hoist, "Transform3D:translation")) == 241
    assert rows(store, "/states/recorded/ring", "StateChange:state") == [
        (0, "STATIC"), (48, "ONTOOL"), (192, "ONBASESLIDE"), (204, "PLACED")]
