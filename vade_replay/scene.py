"""The Scene: everything that stays fixed during a session, built once by ``build_scene``.

This is the only module that touches trimesh. It takes the validated session document and
the bytes of the files it names (so a recording's attachments build the same scene as the
files on disk), converts every length to metres once, and freezes the result: numpy arrays
are made read-only.
"""

from __future__ import annotations

import io
import json
import math
import re
import sys
from dataclasses import dataclass, field, fields, replace
from typing import Final

import numpy as np
import orjson

# ``import trimesh`` imports scipy where it is installed (the test and bench extras): ~0.35 s
# of a command's ~0.75 s start, more than a short golden's whole replay. No trimesh function
# this package calls needs scipy (a plain install has none, and replays the same bits), so a
# command (``vade_replay.cli`` imported first, as the console scripts do) imports trimesh with
# scipy hidden: trimesh's modules that import it optionally do without it (their scipy
# functions would raise if called). scipy itself stays importable after (the benchmark's
# references). A process that uses the package as a library, or has imported scipy or trimesh
# already, imports trimesh as it is. ``tests/test_layers.py`` checks both, with every golden
# and a mesh file of each type. So, in this module: no trimesh call that needs scipy or a
# graph engine (``convex_hull``, ``split``, ``body_count``, ``fix_normals``, ``validate=True``,
# nearest-point queries...): it would work in the tests and fail in the commands.
_WITHOUT_SCIPY = "vade_replay.cli" in sys.modules and "scipy" not in sys.modules \
    and "trimesh" not in sys.modules
if _WITHOUT_SCIPY:
    sys.modules["scipy"] = None  # type: ignore[assignment]  # import scipy: ImportError
try:
    import trimesh
finally:
    if _WITHOUT_SCIPY:
        del sys.modules["scipy"]

from . import arrays
from . import constraints as cn
from . import spatial as sp
from .dynamics.free import COMPOSITIONS, FREE_ROTATIONS
from .dynamics.onbase import SLIDE_INTEGRATORS, TURN_INTEGRATORS
from .errors import SessionError
from .massprops import MassProperties, check, parse_creo_report
from .modes import Mode

UNIT_TO_M = {"m": 1.0, "mm": 1e-3, "in": 0.0254, "cm": 0.01}  # (cm: a mesh file's only)
DEFAULT_GRAVITY_M_S2 = (0.0, 0.0, -9.8)
MESH_TYPES = {".stl": "stl", ".obj": "obj", ".glb": "glb", ".gltf": "gltf", ".ply": "ply",
              ".off": "off"}


# Default sub-steps on the base, chosen by vade-bench (BENCHMARKS.md): at 60 Hz frames,
# yoshida6 turning at two sub-steps is within 1.3e-7 rad of the reference for the gear
# pendulum at ~0.06 ms per simulated second (compiled); analytic4 sliding is exact on a
# still base at any step and within 1e-8 m with the base turning at 1 or 4 rad/s at one
# sub-step a frame. The default step goes with the integrator: the second-order schemes
# keep the 1/180 s chosen for them (analytic, the default before analytic4, is within
# 1e-5 m at 1 rad/s there), so that a recording made with one needs only its integrator
# (and, before slide_onset existed, slide_onset=sub_step) set to replay as it was made.
TURN_STEP_S: Final = 1.0 / 120.0
SLIDE_STEP_S: Final = 1.0 / 180.0
SLIDE_STEPS_S = {"analytic4": 1.0 / 60.0}
SLIDE_ONSETS = ("located", "sub_step")
SLIDE_OFFS = ("located", "frame_end")
FINAL_POSE_CHECKS = ("path", "frame_end")
BLOCK_CUTS = ("blamed", "both")
BLOCK_EVENTS = ("first", "always")
FLIGHT_GRACES = ("touched", "whole_base")
ENVIRONMENT_CONTACTS = ("every_part", "flying")
PASSING_CONTACTS = ("pass", "block")
COAXIAL_FITS = ("radial", "faces")
LANDINGS = ("constraints", "rests")
CONTACT_SWEEPS = ("path", "frame_end")
VELOCITIES = ("world", "relative")
SNAP_VELOCITIES = ("along_constraint", "zero")
RELEASE_VELOCITIES = ("window_fit_corners", "window_fit_stops", "window_fit", "two_frame")
RELEASE_POINTS = ("grip", "cm")


@dataclass(frozen=True)
class Physics:
    """Physical parameters and model choices; all in SI units."""

    model: str = "general"
    gravity: sp.Vec3 = DEFAULT_GRAVITY_M_S2
    gravity_scale_free: float = 0.25
    gravity_scale_slide: float = 1.0
    gravity_scale_rotation: float = 1.0
    free_rotation: str = "momentum"          # paper: constant_omega; rk4, euler: benchmark
    # Measured (tests/test_free_flight.py, 10 s tumbling box): order 6 in one step per 60 Hz
    # frame is 6e-8 rad off a DOP853 reference at 1.1 ms per simulated second; order 4 at
    # 1/240 s steps is 2e-6 rad at 1.9 ms.
    free_rotation_order: int = 6
    free_rotation_max_step_s: float = 1.0 / 60.0
    # paper: two_frame; window_fit: the default before 2026-11-23 (no stop check);
    # window_fit_stops: before window_fit_corners (no corner check)
    release_velocity: str = "window_fit_corners"
    release_window: int = 7
    # The release fit spans at least this long (s), the last release_window samples and
    # those before them within it: 0.1 s, what seven 60 Hz frames span, so a log of
    # unaligned devices (a frame at every stamp) is fitted over as long, not over 18 ms of
    # noise. 0: the window's samples alone, as before this key.
    release_span_s: float = 0.1
    # grip: the release fit follows the point of the part the hand holds it by, and the
    # centre of mass's velocity is the rigid body's (``velocity.estimate``); cm: the
    # centre of mass's own path, as before this key (a part turned in the hand, its centre
    # of mass on a circle, was let go up to 5 % fast at 10 rad/s: a physics audit).
    release_point: str = "grip"
    grab_radius: float = 0.05
    one_hand_max_mass_kg: float = 5.0
    # The paper's middle class of parts: lifted by two hands (both closed on it). At most
    # one_hand_max_mass_kg: no part is lifted by two hands (as before 2026-11-22).
    two_hand_max_mass_kg: float = 15.0
    contact_tolerance: float = 1e-4
    # Constrained motion on the base (defaults for every constraint that gives none).
    friction_static: float = 0.3
    friction_dynamic: float = 0.2
    friction_rotational: float = 0.0         # N m s / rad
    friction_holding_torque: float = 0.0     # N m: static friction about a shaft
    slide_integrator: str = "analytic4"      # analytic: the default before; paper: eq. 4
    # located: stop and slip instants found within the sub-step; sub_step: before 2026-11-22
    slide_onset: str = "located"
    # located: the instant a part slides off the base found within the frame; frame_end:
    # decided at the frame's end, as before 2026-11-22
    slide_off: str = "located"
    # path: a sliding or turning part is PLACED if its path in the frame passes within the
    # final tolerance; frame_end: only where a frame ends, as before 2026-11-22
    final_pose_check: str = "path"
    # blamed: a block cuts at the contact only the motion it stops (slide or turn); both:
    # slide and turn, as before 2026-11-22 (a turn cut so kept its end rate: energy gained)
    block_cut: str = "blamed"
    # first: a block's ContactMade only where the block comes before the final pose in the
    # frame (a part placed first never met the obstacle); always: as before 2026-11-23
    block_event: str = "first"
    # touched: a part that leaves the base passes only the base surfaces it touched as it
    # left (within twice the contact tolerance; ``collision.base_surfaces``), until the two
    # have separated once; the rest of the base stops it. whole_base: it passes the whole
    # base until then, as before 2026-11-23 (a block let go against a wall fell along it
    # through the plate below).
    flight_grace: str = "touched"
    # every_part: a part on the base part (resting, or moving on a plane of it) that the
    # base, or its own move, takes more than 2 mm into the table or another environment
    # object is stopped there (STATIC, hit_environment, lifted out onto it), as a flying
    # part is (one on an axis constraint goes where the base takes it); the base
    # part, which follows the hand, goes on through; and a part let go wholly inside one
    # (pushed in by a hand) is let go on it, where it is. flying: only flying parts meet
    # the environment, from outside, as before this key (a physics trial: a block on a
    # plate lowered into the table rode into it, slid off inside it and fell through it;
    # a part let go inside the table fell out of its underside).
    environment_contact: str = "every_part"
    # block: a part moving on the base that comes within the contact tolerance of it is
    # blocked there, even where it would only pass it (a key between guides; with
    # coaxial_fit faces, a pin with less radial clearance than the tolerance at its bore's
    # rim: lower the tolerance). pass (experimental, 2026-11-23): it goes on to what it
    # moves into; reviews found it stopping a collared pin above its seat and a fast tight
    # pin mid-bore (docs/DEVELOPMENT.md).
    passing_contact: str = "block"
    # radial: on an axis constraint, the part within the constraint's radius (a pin) does
    # not meet the base outside it (a bore's rim): turning and sliding keep every point's
    # distance from the axis (``constraints.Mate.fit_groups``), so a pin passes its
    # rim however tight the fit, a nominal one included. faces: only the base's faces
    # within the radius are left out, as before 2026-11-23 (a pin with less radial
    # clearance than the contact tolerance was held at its bore's rim).
    coaxial_fit: str = "radial"
    # constraints: a flying part that comes onto the base where a constraint of its is
    # recognised (a pin dropped into its bore) goes onto it, or is placed at its final
    # pose, as a release there would. rests: it lies on the base or flies on, as before
    # this key (constraints recognised on release only, as in the paper).
    landing: str = "constraints"
    # path: a move on the base that starts in contact with it (within the tolerance, as a
    # block sliding along a wall does) is stepped along its path against the rest of the
    # base, so it cannot pass through what lies across its way; frame_end: checked at the
    # frame's end alone, as before this key (it passed a rib thinner than a frame's travel).
    # Not where the constraint has radial fits (``coaxial_fit`` radial on an axis).
    contact_sweep: str = "path"
    # world: the recorded velocities of the base and of parts on it (sliding, resting,
    # placed) are world velocities, the base's motion over the frame included, as the
    # schema says; relative: relative to the base (in world axes; zero for the base and
    # for parts at rest on it or placed), as before this key.
    velocities: str = "world"
    # along_constraint: a part that snaps onto a constraint (let go on it, or landing on
    # it in flight) keeps its velocity relative to the base along what the constraint
    # allows (the slide directions, and on an axis its angular momentum about it), losing
    # the rest, as a plastic contact; a kept motion finer than the contact tolerance where
    # friction holds the part is rest (``step._kept_rates``); zero: it starts at rest on
    # the constraint, as in the paper and as before this key (a pin dropped into its bore
    # stopped at the snap).
    snap_velocity: str = "along_constraint"
    turn_integrator: str = "yoshida6"        # paper: eq. 11 once per frame
    # Longest sub-steps on the base, read through turn_step_s / slide_step_s. None: the
    # default below, or onbase_max_step_s where a session sets that (for both).
    onbase_max_step_s: float | None = None
    turn_max_step_s: float | None = None
    slide_max_step_s: float | None = None

    def __post_init__(self) -> None:
        choices: tuple[tuple[str, object, tuple], ...] = (
            ("free_rotation", self.free_rotation, FREE_ROTATIONS),
            ("release_velocity", self.release_velocity, RELEASE_VELOCITIES),
            ("release_point", self.release_point, RELEASE_POINTS),
            ("free_rotation_order", self.free_rotation_order, tuple(COMPOSITIONS)),
            ("slide_integrator", self.slide_integrator, SLIDE_INTEGRATORS),
            ("slide_onset", self.slide_onset, SLIDE_ONSETS),
            ("slide_off", self.slide_off, SLIDE_OFFS),
            ("final_pose_check", self.final_pose_check, FINAL_POSE_CHECKS),
            ("block_cut", self.block_cut, BLOCK_CUTS),
            ("block_event", self.block_event, BLOCK_EVENTS),
            ("flight_grace", self.flight_grace, FLIGHT_GRACES),
            ("environment_contact", self.environment_contact, ENVIRONMENT_CONTACTS),
            ("passing_contact", self.passing_contact, PASSING_CONTACTS),
            ("coaxial_fit", self.coaxial_fit, COAXIAL_FITS),
            ("landing", self.landing, LANDINGS),
            ("contact_sweep", self.contact_sweep, CONTACT_SWEEPS),
            ("velocities", self.velocities, VELOCITIES),
            ("snap_velocity", self.snap_velocity, SNAP_VELOCITIES),
            ("turn_integrator", self.turn_integrator, TURN_INTEGRATORS))
        for name, value, allowed in choices:
            if value not in allowed:
                raise ValueError(f"{name} must be one of {allowed}")

    @property
    def turn_step_s(self) -> float:
        """Longest sub-step of turning on a shaft."""
        if self.turn_max_step_s is not None:
            return self.turn_max_step_s
        return TURN_STEP_S if self.onbase_max_step_s is None else self.onbase_max_step_s

    @property
    def slide_step_s(self) -> float:
        """Longest sub-step of sliding on the base."""
        if self.slide_max_step_s is not None:
            return self.slide_max_step_s
        if self.onbase_max_step_s is not None:
            return self.onbase_max_step_s
        return SLIDE_STEPS_S.get(self.slide_integrator, SLIDE_STEP_S)

    @property
    def gravity_slide(self) -> sp.Vec3:
        return sp.scale(self.gravity, self.gravity_scale_slide)

    @property
    def gravity_rotation(self) -> sp.Vec3:
        return sp.scale(self.gravity, self.gravity_scale_rotation)

    @property
    def gravity_free(self) -> sp.Vec3:
        return sp.scale(self.gravity, self.gravity_scale_free)


PAPER_DEFAULTS = {"free_rotation": "constant_omega", "release_velocity": "two_frame",
                  "release_point": "cm",  # the paper's two poses of the part
                  "slide_integrator": "paper", "turn_integrator": "paper",
                  "slide_off": "frame_end",  # the paper decides sliding frame by frame
                  "final_pose_check": "frame_end", "block_cut": "both",
                  # The paper recognises constraints on release only, and checks a move on
                  # the base at the frame's end.
                  "landing": "rests", "contact_sweep": "frame_end",
                  # The paper's part starts at rest on the constraint it is let go on.
                  "snap_velocity": "zero"}
LENGTH_FIELDS = ("grab_radius", "contact_tolerance")


def _frozen(array) -> np.ndarray:
    out = np.array(array, dtype=np.float64, copy=True)
    out.setflags(write=False)
    return out


@dataclass(frozen=True, eq=False)
class Body:
    """A rigid body's fixed data: geometry in its own frame (metres) and mass properties."""

    name: str
    vertices: np.ndarray            # (N, 3) float64, read-only
    faces: np.ndarray               # (M, 3) int64, read-only
    mass_kg: float
    center_of_mass: sp.Vec3         # part frame
    inertia_cm: sp.Mat3             # at the CM, part-frame axes
    principal_moments: sp.Vec3      # ascending
    part_from_principal: sp.Quat
    radius_about_cm: float          # farthest vertex from the CM
    bbox_min: sp.Vec3               # part frame
    bbox_max: sp.Vec3
    reach_from_origin: float        # the box's farthest corner from the part frame's origin
    initial_pose: sp.Pose
    initial_mode: Mode
    color: tuple[int, ...] | None = None
    assembly: cn.Assembly | None = None  # constraints with the base part (parts only)


# Devices of the tracker stream that are not tools.
HAND_DEVICES = ("head", "left_hand", "right_hand")
# The grip of a part held by both hands, in its Held and its events (not a device).
BOTH_HANDS: Final = "both_hands"


@dataclass(frozen=True)
class Tool:
    """A tool that lifts parts too heavy for a hand (a hoist's hook, tongs): a tracked device
    of its own name, whose grip attaches the part nearest it (ONTOOL) and detaches it."""

    name: str              # its device in the tracker stream
    max_mass_kg: float     # the heaviest part it lifts
    grab_radius: float     # m: how near its device a part's bounding box must be


@dataclass(frozen=True, eq=False)
class Scene:
    """Parts, base part, environment and physics of a session; never changes while it runs."""

    name: str
    units: str
    physics: Physics
    parts: tuple[Body, ...]                 # sorted by name
    base: Body | None
    hand_from_base: sp.Pose
    environment: tuple[Body, ...]           # sorted by name
    part_index: dict = field(default_factory=dict)
    tools: tuple[Tool, ...] = ()            # sorted by name
    # The base stands where it is (a fixture on the table): the left hand does not carry
    # it, and grabs parts as the right hand does.
    base_fixed: bool = False

    @property
    def base_in_hand(self) -> bool:
        """The left hand carries the base part (so it grabs nothing)."""
        return self.base is not None and not self.base_fixed

    def part(self, name: str) -> Body:
        return self.parts[self.part_index[name]]

    def tool(self, name: str) -> Tool | None:
        for tool in self.tools:
            if tool.name == name:
                return tool
        return None


def _vec(values, factor: float = 1.0) -> sp.Vec3:
    return (float(values[0]) * factor, float(values[1]) * factor, float(values[2]) * factor)


def pose_from_doc(doc: dict | None, length_factor: float, *, where: str, file: str) -> sp.Pose:
    """A pose field of a session file: position in session units, rotation as xyzw or euler."""
    if not doc:
        return sp.IDENTITY
    position = _vec(doc.get("position", (0.0, 0.0, 0.0)), length_factor)
    if "xyzw" in doc:
        try:
            x, y, z, w = (float(v) for v in doc["xyzw"])
            rotation = sp.quat_normalize((x, y, z, w))
        except ValueError as exc:
            raise SessionError(str(exc), file=file, field=f"{where}.xyzw") from None
    elif "euler_deg" in doc:
        rotation = sp.quat_from_euler_deg(*(float(v) for v in doc["euler_deg"]))
    else:
        rotation = sp.IDENTITY_QUAT
    return sp.Pose(position, rotation)


def _gear_mesh(radius: float, height: float, teeth: int, tooth_depth: float,
               inner_radius: float | None, samples_per_tooth: int = 8) -> trimesh.Trimesh:
    """A disc with a toothed rim (and an optional bore), along z, centred at the origin."""
    n = teeth * samples_per_tooth
    angles = [2.0 * math.pi * i / n for i in range(n)]
    outer = []
    for i, a in enumerate(angles):
        phase = (i % samples_per_tooth) / samples_per_tooth
        r = radius if phase < 0.5 else radius - tooth_depth
        outer.append((r * math.cos(a), r * math.sin(a)))
    z0, z1 = -0.5 * height, 0.5 * height
    # Rings of vertices (x, y from the lists above, z per ring) and faces as index arrays:
    # the same numbers as written out vertex by vertex, built by numpy.
    k = np.arange(n)
    k1 = (k + 1) % n

    def ring(xy: list[tuple[float, float]], z: float) -> np.ndarray:
        return np.column_stack([np.array(xy), np.full(n, z)])

    if inner_radius:
        inner = [(inner_radius * math.cos(a), inner_radius * math.sin(a)) for a in angles]
        # Rings: outer bottom, outer top, inner bottom, inner top.
        vertices = np.concatenate([ring(outer, z0), ring(outer, z1), ring(inner, z0),
                                   ring(inner, z1)])
        ob, ot, ib, it = 0, n, 2 * n, 3 * n
        faces_of_k = [(ob + k, ob + k1, ot + k1), (ob + k, ot + k1, ot + k),  # outer wall
                      (ib + k, it + k1, ib + k1), (ib + k, it + k, it + k1),  # bore wall
                      (ot + k, ot + k1, it + k1), (ot + k, it + k1, it + k),  # top annulus
                      (ob + k, ib + k1, ob + k1), (ob + k, ib + k, ib + k1)]  # bottom
    else:
        vertices = np.concatenate([ring(outer, z0), ring(outer, z1),
                                   np.array([(0.0, 0.0, z0), (0.0, 0.0, z1)])])
        cb, ct = np.full(n, 2 * n), np.full(n, 2 * n + 1)
        faces_of_k = [(k, k1, n + k1), (k, n + k1, n + k), (n + k, n + k1, ct), (k, cb, k1)]
    # Face m of vertex k is row len(faces_of_k) * k + m: the order of a loop over k.
    faces = np.stack([np.stack(f, axis=1) for f in faces_of_k], axis=1).reshape(-1, 3)
    # Wound outward by construction, every face: trimesh.repair.fix_normals would find nothing
    # to fix (tests/test_session.py holds the winding on 288 gears), and it cost 1.6 ms of a
    # gear session's ~9 ms setup (the volume computed once more, the face graph walked).
    return trimesh.Trimesh(vertices=vertices, faces=faces, process=True)


def _mesh_from_shape(shape: dict, length_factor: float, files: dict[str, bytes], *,
                     where: str, file: str, shape_at: str | None = None) -> trimesh.Trimesh:
    """The shape's triangle mesh in the body's frame, in metres. ``shape_at``: where the
    shape is in the file (``WHERE.shape``, or a compound's ``...children[i]``)."""
    at = f"{where}.shape" if shape_at is None else shape_at
    kind = shape["type"]
    f = length_factor
    if kind == "compound":
        # Several shapes, each at its own pose, as one mesh (e.g. a block with a shaft).
        meshes = []
        for i, child in enumerate(shape["children"]):
            mesh = _mesh_from_shape(child, f, files, where=where, file=file,
                                    shape_at=f"{at}.children[{i}]")
            pose = pose_from_doc(child.get("pose"), f, where=f"{at}.children[{i}].pose",
                                 file=file)
            meshes.append(trimesh.Trimesh(vertices=arrays.posed_points(mesh.vertices, pose),
                                          faces=mesh.faces, process=False))
        combined: trimesh.Trimesh = trimesh.util.concatenate(meshes)  # type: ignore[assignment]
        return combined
    if kind == "box":
        return trimesh.creation.box(extents=[v * f for v in shape["size"]])
    sections = int(shape.get("sections", 48))
    if kind == "cylinder":
        return trimesh.creation.cylinder(radius=shape["radius"] * f, height=shape["height"] * f,
                                         sections=sections)
    if kind == "tube":
        if shape["inner_radius"] >= shape["radius"]:
            raise SessionError("inner_radius must be smaller than radius", file=file,
                               field=f"{at}.inner_radius")
        return trimesh.creation.annulus(r_min=shape["inner_radius"] * f, r_max=shape["radius"] * f,
                                        height=shape["height"] * f, sections=sections)
    if kind == "gear":
        depth = shape.get("tooth_depth", 0.1 * shape["radius"])
        inner = shape.get("inner_radius")
        if depth >= shape["radius"] or (inner and inner >= shape["radius"] - depth):
            raise SessionError("gear teeth or bore do not fit inside the radius", file=file,
                               field=f"{at}")
        return _gear_mesh(shape["radius"] * f, shape["height"] * f, int(shape["teeth"]),
                          depth * f, inner * f if inner else None)
    # A mesh file: its own units, else the session's.
    name = shape["file"]
    if name not in files:
        raise SessionError(f"mesh file {name!r} not found", file=file, field=f"{at}.file")
    suffix = "." + name.rsplit(".", 1)[-1].lower() if "." in name else ""
    if suffix not in MESH_TYPES:
        raise SessionError(f"unsupported mesh type {suffix!r} (use {', '.join(MESH_TYPES)})",
                           file=file, field=f"{at}.file")
    bad = _non_finite_numbers(files[name], MESH_TYPES[suffix])
    if bad:
        # (trimesh's processing drops the faces that name such a vertex: a CAD user's trial
        # saw a part called not watertight for it, and a base lose five faces silently.)
        raise SessionError(f"mesh {name!r} holds {bad} coordinate{'' if bad == 1 else 's'} that "
                           f"{'is' if bad == 1 else 'are'} not finite (NaN or infinite): "
                           "fix the export", file=file, field=f"{at}.file")
    try:
        loaded = trimesh.load(io.BytesIO(files[name]), file_type=MESH_TYPES[suffix], force="mesh",
                              process=True)
    except ImportError:
        # trimesh reaching for an optional module to read what it could not (a CAD user's
        # trial: a binary STL named .obj said "No module named 'charset_normalizer'").
        raise SessionError(f"cannot read mesh {name!r} as {MESH_TYPES[suffix].upper()}: is "
                           f"it a {suffix} file? (its name's ending gives the type)",
                           file=file, field=f"{at}.file") from None
    except Exception as exc:  # trimesh raises many types for a corrupt file
        # Named from the session that names it, as every other error of it is.
        raise SessionError(f"cannot read mesh {name!r}: {exc}", file=file,
                           field=f"{at}.file") from None
    if isinstance(loaded, trimesh.Trimesh) and len(loaded.faces):
        # A triangle that names one vertex twice (an exporter's leftover, or two corners
        # merged as one by the loading) has no area and bounds nothing, but it made a
        # closed solid "not watertight" (a CAD user's trial: sent to give mass properties).
        corners = np.asarray(loaded.faces)
        repeated = ((corners[:, 0] == corners[:, 1]) | (corners[:, 1] == corners[:, 2])
                    | (corners[:, 0] == corners[:, 2]))
        if repeated.any():
            loaded = trimesh.Trimesh(vertices=loaded.vertices, faces=corners[~repeated],
                                     process=False)
            loaded.remove_unreferenced_vertices()  # (a vertex only such a face named)
    if not isinstance(loaded, trimesh.Trimesh) or len(loaded.faces) == 0:
        raise SessionError(f"mesh file {name!r} holds no triangles", file=file,
                           field=f"{at}.file")
    placed = np.asarray(loaded.vertices)
    if not np.isfinite(placed).all():
        # Its numbers finite, its vertices not: a glTF node's transform of NaN (a helper's
        # trial: then "mass properties hold a non-finite number", or a constraint that
        # fits "no base faces ... nan x nan x nan m across").
        bad = int(np.count_nonzero(~np.isfinite(placed)))
        raise SessionError(f"mesh {name!r} places {bad} coordinate{'' if bad == 1 else 's'} "
                           "of its vertices at NaN or infinity (a transform in the file?): "
                           "fix the export", file=file, field=f"{at}.file")
    mesh_factor = UNIT_TO_M[shape["units"]] if "units" in shape else f
    if mesh_factor == 1.0:
        return loaded
    # Scaled element by element (trimesh's apply_scale multiplies by a matrix, in BLAS).
    return trimesh.Trimesh(vertices=np.asarray(loaded.vertices) * mesh_factor,
                           faces=loaded.faces, process=False)


_NON_FINITE = re.compile(rb"(?<![A-Za-z_])[-+]?(nan|inf|infinity)(?![A-Za-z_])", re.IGNORECASE)


def _non_finite_numbers(data: bytes, kind: str) -> int:
    """How many numbers of a mesh file are NaN or infinite: a binary STL's or binary PLY's
    coordinates read as numbers where the file lays them out, the words of a text file (an
    ASCII STL, OBJ, OFF or PLY), a glTF's or GLB's vertex positions as trimesh's own reader
    gives them before any processing. 0 where that cannot be told (the mesh's loading then
    says what is wrong with the file)."""
    if kind == "stl" and not data[:5].lower() == b"solid" and len(data) >= 84:
        count = int.from_bytes(data[80:84], "little")
        if len(data) == 84 + 50 * count:
            records = np.frombuffer(data, dtype=np.dtype([("normal", "<f4", 3),
                                                           ("corners", "<f4", 9),
                                                           ("attribute", "<u2")]),
                                    count=count, offset=84)
            return int(np.count_nonzero(~np.isfinite(records["corners"])))
        return 0
    if kind in ("stl", "obj"):
        # Their vertex lines only ("v x y z", "vertex x y z"): a name or a comment may hold
        # such a word.
        key = b"v " if kind == "obj" else b"vertex"
        return sum(len(_NON_FINITE.findall(line)) for line in data.splitlines()
                   if line.lstrip().startswith(key))
    if kind == "ply" and b"format ascii" in data[:200]:
        # After the header: a comment in it may hold such a word (a helper's trial: "comment
        # made with inf precision" refused a sound file).
        end = data.find(b"end_header")
        return len(_NON_FINITE.findall(data[end:])) if end >= 0 else 0
    if kind == "off":
        # Not its comments ("# ..." lines, or the rest of a line after "#").
        return sum(len(_NON_FINITE.findall(line.split(b"#", 1)[0]))
                   for line in data.splitlines())
    if kind == "ply":
        return _binary_ply_non_finite(data)
    if kind in ("glb", "gltf"):
        return _gltf_non_finite(data, kind)
    return 0


# A binary PLY's scalar property types (trimesh's names, the specification's and the wild's).
_PLY_TYPES: Final = {"char": "i1", "uchar": "u1", "short": "i2", "ushort": "u2", "int": "i4",
                     "uint": "u4", "float": "f4", "double": "f8", "int8": "i1", "uint8": "u1",
                     "int16": "i2", "uint16": "u2", "int32": "i4", "uint32": "u4",
                     "int64": "i8", "uint64": "u8", "float16": "f2", "float32": "f4",
                     "float64": "f8"}


def _binary_ply_non_finite(data: bytes) -> int:
    """The NaN or infinite x, y, z of a binary PLY's vertex element, read with numpy from
    the layout its header declares (where trimesh reads them). 0 where the layout is not one
    of fixed-size records up to the vertices (an element with a list property before them,
    or in them: no exporter seen writes one), or the file is short of them."""
    lines: list[list[str]] = []
    start = 0
    while True:  # the header's lines, to the one that ends it (as trimesh reads them)
        end = data.find(b"\n", start, 1 << 20)
        if end < 0:
            return 0
        words = data[start:end].decode("latin-1").split()
        start = end + 1
        if "end_header" in words:
            break
        lines.append(words)
    formats = [line[1] for line in lines if len(line) > 1 and line[0] == "format"]
    if formats not in (["binary_little_endian"], ["binary_big_endian"]):
        return 0
    order = ">" if formats[0] == "binary_big_endian" else "<"
    offset = start
    name = ""
    count = -1
    fields: list[tuple[str, str]] = []
    for line in lines + [["element", "", "0"]]:
        if line and line[0] == "element":
            if name == "vertex":  # the vertex element's properties are all read
                return _vertex_non_finite(data, offset, count, fields)
            if count >= 0:  # the element before this one, fixed-size records, passed
                offset += count * (np.dtype(fields).itemsize if fields else 0)
            if len(line) != 3 or not line[2].isdigit():
                return 0
            name, count, fields = line[1], int(line[2]), []
        elif line and line[0] == "property" and count >= 0:
            if len(line) != 3 or line[1] not in _PLY_TYPES:
                return 0  # a list property: the records' size is not fixed
            fields.append((f"{len(fields)}_{line[2]}", order + _PLY_TYPES[line[1]]))
    return 0


def _vertex_non_finite(data: bytes, offset: int, count: int,
                       fields: list[tuple[str, str]]) -> int:
    """The NaN or infinite of a PLY vertex element's x, y and z at ``offset``."""
    layout = np.dtype(fields)
    if not fields or count == 0 or offset + count * layout.itemsize > len(data):
        return 0
    records = np.frombuffer(data, dtype=layout, count=count, offset=offset)
    bad = 0
    for key, _ in fields:
        if key.split("_", 1)[1] in ("x", "y", "z") and records.dtype[key].kind == "f":
            bad += int(np.count_nonzero(~np.isfinite(records[key])))
    return bad


def _gltf_non_finite(data: bytes, kind: str) -> int:
    """The NaN or infinite vertex coordinates of a glTF's or GLB's triangle meshes, as
    trimesh's reader gives them before building (and processing) its meshes: the accessors'
    numbers only, the materials' images left unread."""
    from trimesh.exchange import gltf
    reader = gltf.load_glb if kind == "glb" else gltf.load_gltf
    try:
        read = reader(io.BytesIO(data), skip_materials=True)
        geometry = read["geometry"].values()
        return sum(int(np.count_nonzero(~np.isfinite(np.asarray(g["vertices"], dtype=float))))
                   for g in geometry if "faces" in g and "vertices" in g)
    except Exception:  # the loading itself then says what is wrong with the file
        return 0


def even_inertia_trace(vertices: np.ndarray, faces: np.ndarray, density: float) -> float:
    """The trace of the inertia tensor at the centre of mass (kg m^2) of a closed mesh
    at a uniform density: what ``replay.mass_warnings`` holds given inertia to."""
    mass = trimesh.triangles.mass_properties(triangles=vertices[faces], density=density)
    return float(np.trace(mass.inertia))  # type: ignore[arg-type]


def _mass_properties(doc: dict, mesh: trimesh.Trimesh, length_factor: float,
                     files: dict[str, bytes], *, where: str, file: str) -> MassProperties:
    """A body's mass properties: from its ``density`` or ``mass_properties``, scaled to its
    ``mass`` (kg) where a part gives one (with neither, a uniform density)."""
    props = _spread(doc, mesh, length_factor, files, where=where, file=file)
    if "mass" not in doc:
        return props
    mass = float(doc["mass"])
    k = mass / props.mass_kg
    return check(MassProperties(mass, props.center_of_mass,
                                tuple(tuple(x * k for x in row)  # type: ignore[misc]
                                      for row in props.inertia_cm)),
                 file=file, field=f"{where}.mass")


def _spread(doc: dict, mesh: trimesh.Trimesh, length_factor: float,
            files: dict[str, bytes], *, where: str, file: str) -> MassProperties:
    given = doc.get("mass_properties")
    if given and "file" in given:
        name = given["file"]
        if name not in files:
            raise SessionError(f"mass-property report {name!r} not found", file=file,
                               field=f"{where}.mass_properties.file")
        try:
            text = files[name].decode("utf-8", errors="replace")
        except AttributeError:
            text = str(files[name])
        return parse_creo_report(text, file=name,
                                 products_sign=given.get("products_sign", "tensor"))
    if given:
        f = length_factor
        props = MassProperties(
            float(given["mass"]), _vec(given["center_of_mass"], f),
            tuple(_vec(row, f * f) for row in given["inertia"]))  # type: ignore[arg-type]
        return check(props, file=file, field=f"{where}.mass_properties")
    if "density" not in doc and "mass" not in doc:
        raise SessionError("give its density, its mass or its mass_properties", file=file,
                           field=where)
    if not mesh.is_watertight:
        size = float(np.max(mesh.extents)) if len(mesh.vertices) else 0.0
        if '"file"' not in json.dumps(doc["shape"]) and size < _OPEN_WHEN_SMALL_M:
            # A shape of its own (box, tube, ...) is closed at any size a hand holds, but
            # trimesh drops faces of one a millimetre or so across (a researcher's trial: a
            # metre session labelled "in", a 0.05 in tube, was told to give
            # mass_properties).
            raise SessionError(
                f"it is {size * 1e3:.3g} mm across, too small for its mesh to close: are "
                f"the session's units right? (lengths are in its units, "
                f"{_UNIT_NAMES.get(length_factor, '')})", file=file, field=f"{where}.shape")
        raise SessionError(
            "mesh is not watertight, so its volume and inertia are undefined; give "
            "mass_properties (a CAD report or the numbers) for this part"
            + ("; or leave out the base's density: its mass is not used" if where == "base"
               else ""), file=file, field=f"{where}.shape")
    if not mesh.is_winding_consistent:
        # Watertight, but some faces wound the other way (face inward): the volume comes
        # out as the difference of the two sides, a wrong mass without a word.
        raise SessionError(
            "the mesh's faces are not wound consistently (some face inward), so its volume, "
            "mass and inertia would be wrong; fix its normals (trimesh.repair.fix_normals) "
            "or give mass_properties for this part", file=file, field=f"{where}.shape")
    # What Trimesh.mass_properties calls, with the density given: the same numbers as a
    # copy of the mesh with its density set, without the copy (and its cache's hashing).
    mass = trimesh.triangles.mass_properties(triangles=mesh.triangles,
                                             crosses=mesh.triangles_cross,
                                             density=float(doc.get("density", 1.0)))
    if float(mass.volume) < 0.0:
        raise SessionError(
            "the mesh's faces all point inward (its volume comes out negative): its normals "
            "are inverted; flip them (trimesh: mesh.invert()) or export it again",
            file=file, field=f"{where}.shape")
    props = MassProperties(float(mass.mass), _vec(mass.center_mass),
                           tuple(_vec(row) for row in mass.inertia))  # type: ignore[arg-type, union-attr]
    return check(props, file=file, field=f"{where}.density" if "density" in doc
                 else f"{where}.mass")


def _principal(props: MassProperties) -> tuple[sp.Vec3, sp.Quat]:
    moments, axes = sp.symmetric_eigen(props.inertia_cm)
    return moments, sp.quat_from_matrix(axes)


# Keys of a part's document that do not change its geometry or mass.
_PLACEMENT_KEYS = ("name", "pose", "color", "assembly", "hand_from_base", "fixed")


def _body(doc: dict, length_factor: float, files: dict[str, bytes], *, where: str, file: str,
          mode: Mode, needs_mass: bool, shapes: dict | None = None) -> Body:
    # Parts made alike (a tray of identical screws) share their mesh and mass properties:
    # ``shapes`` remembers them for one scene, keyed by everything else in the document.
    # (orjson: json.dumps of the key was most of a 200-part scene's build.)
    key = _shape_key([{k: v for k, v in doc.items() if k not in _PLACEMENT_KEYS},
                      length_factor, needs_mass])
    made = shapes.get(key) if shapes is not None else None
    if made is None:
        made = _geometry(doc, length_factor, files, where=where, file=file,
                         needs_mass=needs_mass)
        if shapes is not None:
            shapes[key] = made
    vertices, faces, props, moments, part_from_principal, radius, lo, hi, reach = made
    return Body(
        name=doc["name"], vertices=vertices, faces=faces, mass_kg=props.mass_kg,
        center_of_mass=props.center_of_mass, inertia_cm=props.inertia_cm,
        principal_moments=moments, part_from_principal=part_from_principal,
        radius_about_cm=radius, bbox_min=lo, bbox_max=hi, reach_from_origin=reach,
        initial_pose=pose_from_doc(doc.get("pose"), length_factor, where=f"{where}.pose",
                                   file=file),
        initial_mode=mode, color=tuple(doc["color"]) if "color" in doc else None)


# A part smaller than this across is refused as a units slip (0.1 mm).
_MIN_SIZE_M = 1e-4
# A shape of the session's own (not a mesh file) this small left open by trimesh is asked
# about as a units slip (5 mm); a larger one is an open mesh as a file's is.
_OPEN_WHEN_SMALL_M = 5e-3
_UNIT_NAMES = {factor: name for name, factor in UNIT_TO_M.items()}


def _geometry(doc: dict, length_factor: float, files: dict[str, bytes], *, where: str,
              file: str, needs_mass: bool):
    mesh = _mesh_from_shape(doc["shape"], length_factor, files, where=where, file=file)
    # (A mesh whose vertices all merged, a shape in metres read as mm, has no extents.)
    extents = mesh.extents if len(mesh.vertices) else None
    size = float(np.max(extents)) if extents is not None else 0.0
    if size < _MIN_SIZE_M:
        # Nothing a hand assembles is this small: lengths in metres in a mm file, most likely
        # (and trimesh's mass properties of it are round-off).
        from_file = '"file"' in json.dumps(doc["shape"])
        raise SessionError(f"it is {size * 1e3:.3g} mm across: are the session's units "
                           f"right? (lengths are in its units, {_UNIT_NAMES.get(length_factor, '')}"
                           + ("; a mesh file in another unit names it in the shape's "
                              '"units"' if from_file else "") + ")",
                           file=file, field=f"{where}.shape")
    if needs_mass:
        props = _mass_properties(doc, mesh, length_factor, files, where=where, file=file)
    else:
        props = MassProperties(1.0, _vec(mesh.centroid), ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0),
                                                          (0.0, 0.0, 1.0)))
    moments, part_from_principal = _principal(props)
    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    radius = float(np.max(arrays.norms(vertices - np.array(props.center_of_mass))))
    faces = np.array(mesh.faces, dtype=np.int64)
    faces.setflags(write=False)
    lo, hi = _vec(vertices.min(axis=0)), _vec(vertices.max(axis=0))
    reach = math.sqrt(sum(max(-a, b) ** 2 for a, b in zip(lo, hi)))
    return _frozen(vertices), faces, props, moments, part_from_principal, radius, lo, hi, reach


def _shape_key(doc: list) -> bytes:
    """The text a shape is known by in one scene: the document sorted by key. orjson's,
    except where it would write ``null`` (for None, and for NaN and the infinities, which
    ``json`` keeps apart) or cannot write a number (an integer past 64 bits): there
    ``json``'s, whose separators orjson never writes, so the two never give one key."""
    try:
        key = orjson.dumps(doc, option=orjson.OPT_SORT_KEYS)
    except orjson.JSONEncodeError:
        key = b"null"
    if b"null" in key:
        return json.dumps(doc, sort_keys=True).encode()
    return key


def _feature(doc: dict, key: str, f: float) -> tuple[sp.Vec3, sp.Vec3]:
    return _vec(doc["point"], f), _vec(doc[key])


# A part or the base part larger than this across is drawn in other units than the
# session's (CAD exports in millimetres into a metre session are 1000 times too large):
# ``replay.mesh_scale_warnings`` warns of it, and a constraint that does not fit says it.
# (One too small is refused: ``_OPEN_WHEN_SMALL_M``.)
MESH_LARGEST_M = 5.0


def oversize_across(body: Body, f: float) -> str | None:
    """A body's extents in a session's units (``f``: metres a unit), "a x b x c", where it is
    over ``MESH_LARGEST_M`` across; None where it is not."""
    size = [body.bbox_max[k] - body.bbox_min[k] for k in range(3)]
    if max(size) <= MESH_LARGEST_M:
        return None
    return " x ".join(f"{extent / f:.3g}" for extent in size)


def _oversize(part: Body, base: Body, f: float) -> str:
    """What a constraint's error adds where its part or base is too large to be a part of
    an assembly (a CAD user's trial: a millimetre mesh in a metre session was told only to
    check the constraint's point, direction and radius, the units warning never reached)."""
    for body, which in ((base, "the base part"), (part, "the part")):
        across = oversize_across(body, f)
        if across is not None:
            return (f" ({which} is {across} {_UNIT_NAMES.get(f, 'units')} across: a mesh "
                    "drawn in millimetres? give its shape.units)")
    return ""


def _assembly(doc: dict, part: Body, base: Body, physics: Physics, f: float, *, where: str,
              file: str) -> cn.Assembly:
    """A part's ``assembly`` block: mates with the base and the final pose, in metres."""
    mates = []
    for i, mdoc in enumerate(doc.get("constraints", [])):
        here = f"{where}.constraints[{i}]"
        kind = mdoc["type"]
        key = "direction" if kind == "axis" else "normal"
        for side in ("part", "base"):
            features = mdoc[side] if isinstance(mdoc[side], list) else [mdoc[side]]
            for j, feature in enumerate(features):
                if not any(float(v) for v in feature[key]):
                    at = f"{here}.{side}" + (f"[{j}]" if kind == "planes" else "")
                    raise SessionError(f"the {key} is a zero vector: it must point somewhere",
                                       file=file, field=f"{at}.{key}")
        if kind == "planes":
            part_features = [_feature(d, key, f) for d in mdoc["part"]]
            base_features = [_feature(d, key, f) for d in mdoc["base"]]
        else:
            part_features = [_feature(mdoc["part"], key, f)]
            base_features = [_feature(mdoc["base"], key, f)]
        tol = mdoc.get("tolerance", {})
        friction = mdoc.get("friction", {})
        try:
            mate = cn.build_mate(
                name=mdoc.get("name", f"{kind}{i}"), kind=kind,
                base_points=[p for p, _ in base_features], base_dirs=[d for _, d in base_features],
                part_points=[p for p, _ in part_features], part_dirs=[d for _, d in part_features],
                radius=float(mdoc.get("radius", 0.0)) * f,
                distance_tolerance=float(tol.get("distance",
                                                 cn.DEFAULT_DISTANCE_TOLERANCE_M / f)) * f,
                angle_tolerance=math.radians(float(tol.get("angle_deg",
                                                           cn.DEFAULT_ANGLE_TOLERANCE_DEG))),
                slide=bool(mdoc.get("slide", True)), turn=bool(mdoc.get("turn", kind == "axis")),
                static_friction=float(friction.get("static", physics.friction_static)),
                dynamic_friction=float(friction.get("dynamic", physics.friction_dynamic)),
                rotational_friction=float(friction.get("rotational",
                                                       physics.friction_rotational)),
                holding_torque=float(friction.get("holding_torque",
                                                  physics.friction_holding_torque)),
                leave_when=mdoc.get("leave_when", "center_of_mass_off"),
                part_vertices=np.asarray(part.vertices), part_faces=np.asarray(part.faces),
                mass_kg=part.mass_kg, center_of_mass=part.center_of_mass,
                inertia_cm=part.inertia_cm, base_vertices=np.asarray(base.vertices),
                base_faces=np.asarray(base.faces), geometry_tol=physics.contact_tolerance,
                coaxial_fit=physics.coaxial_fit)
        except ValueError as exc:
            raise SessionError(str(exc) + _oversize(part, base, f), file=file,
                               field=here) from None
        if kind == "axis" and len(mate.base_feature_faces) == 0:
            raise SessionError("no base faces lie within the axis radius: check point, "
                               "direction and radius" + _oversize(part, base, f),
                               file=file, field=f"{here}.base")
        if kind != "axis" and len(mate.base_feature_faces) == 0:
            raise SessionError("no base faces lie in the plane: check point and normal"
                               + _oversize(part, base, f), file=file, field=f"{here}.base")
        mates.append(mate)
    final = doc.get("final_pose")
    final_tol = doc.get("final_tolerance", {})
    return cn.Assembly(
        mates=tuple(mates),
        final_pose=pose_from_doc(final, f, where=f"{where}.final_pose", file=file)
        if final else None,
        final_distance=float(final_tol.get("distance", cn.DEFAULT_FINAL_DISTANCE_M / f)) * f,
        final_angle=math.radians(float(final_tol.get("angle_deg", cn.DEFAULT_FINAL_ANGLE_DEG))))


# The fields of Physics that hold a float and an int, from their defaults: annotations are
# text in the Python sources and types in the compiled build (tests/test_native.py holds
# these to the annotations).
FLOAT_FIELDS = frozenset([f.name for f in fields(Physics) if type(f.default) is float]
                         + ["onbase_max_step_s", "turn_max_step_s", "slide_max_step_s"])
INT_FIELDS = frozenset(f.name for f in fields(Physics) if type(f.default) is int)


def physics_from_doc(doc: dict, length_factor: float, *, file: str | None = None,
                     defaults: dict | None = None) -> Physics:
    """Physics from a session's ``physics`` block, lengths converted to metres. ``defaults``
    (SI, lengths in metres) stand for this version's where the block gives no value: the
    physics a recording was made with (``replay.as_made``)."""
    values = dict(doc)
    restored = defaults or {}
    model = values.get("model", restored.get("model", "general"))
    if model == "paper":
        # The paper's schemes where the session names none: those of the time a recording
        # was made, where it says (``defaults``), else today's.
        for key, value in PAPER_DEFAULTS.items():
            values.setdefault(key, restored.get(key, value))
    if "gravity" in values:
        values["gravity"] = _vec(values["gravity"], length_factor)
    for key in LENGTH_FIELDS:
        if key in values:
            values[key] = float(values[key]) * length_factor
    # (Names of their own: compiled, a loop variable keeps the type of its first use.)
    for name, default in restored.items():
        values.setdefault(name, tuple(default) if isinstance(default, list) else default)
    # A whole number given for a real parameter ("friction_static": 0) is that float, and a
    # count written as a float ("release_window": 7.0, which JSON Schema calls an integer)
    # is that int: the simulation sees the same value whichever way it was written, and
    # the compiled build (which checks the types) the same as the Python sources.
    for name, given in list(values.items()):
        if name in FLOAT_FIELDS and type(given) is int:
            values[name] = float(given)
        elif name in INT_FIELDS and type(given) is float:
            if not given.is_integer():
                raise SessionError(f"must be a whole number, got {given!r}", file=file,
                                   field=f"physics.{name}")
            values[name] = int(given)
    return Physics(**values)


def build_scene(session: dict, files: dict[str, bytes], *, file: str = "<session>",
                physics_defaults: dict | None = None) -> Scene:
    """Build the frozen Scene from a validated session document and the files it names
    (``physics_defaults``: see ``physics_from_doc``)."""
    units = session.get("units", "m")
    f = UNIT_TO_M[units]
    physics = physics_from_doc(session.get("physics", {}), f, file=file,
                               defaults=physics_defaults)
    names = [p["name"] for p in session["parts"]]
    if len(set(names)) != len(names):
        twice = sorted({n for n in names if names.count(n) > 1})
        raise SessionError(f"part names must be unique: {', '.join(map(repr, twice))} "
                           f"{'is' if len(twice) == 1 else 'are'} given to more than one part",
                           file=file, field="parts")
    shapes: dict = {}
    parts = tuple(sorted(
        (_body(doc, f, files, where=f"parts[{i}]", file=file, mode=Mode.STATIC, needs_mass=True,
               shapes=shapes)
         for i, doc in enumerate(session["parts"])), key=lambda b: b.name))
    base = None
    hand_from_base = sp.IDENTITY
    base_fixed = False
    if "base" in session:
        # The base part is held in the left hand, or fixed (a fixture on the table): its
        # mass is not used unless given.
        base_fixed = bool(session["base"].get("fixed", False))
        if base_fixed and "hand_from_base" in session["base"]:
            raise SessionError("a fixed base is not held: hand_from_base has no use with "
                               "base.fixed", file=file, field="base.hand_from_base")
        base = _body(session["base"], f, files, where="base", file=file,
                     mode=Mode.STATIC if base_fixed else Mode.INHAND,
                     needs_mass="density" in session["base"]
                     or "mass_properties" in session["base"])
        hand_from_base = pose_from_doc(session["base"].get("hand_from_base"), f,
                                       where="base.hand_from_base", file=file)
    environment = tuple(sorted(
        (_body(doc, f, files, where=f"environment[{i}]", file=file, mode=Mode.STATIC,
               needs_mass=False)
         for i, doc in enumerate(session.get("environment", []))), key=lambda b: b.name))
    docs = {doc["name"]: (i, doc) for i, doc in enumerate(session["parts"])}
    with_assembly = []
    for body in parts:
        i, doc = docs[body.name]
        if "assembly" in doc:
            if base is None:
                raise SessionError("a part with assembly constraints needs a base part",
                                   file=file, field=f"parts[{i}].assembly")
            body = replace(body, assembly=_assembly(doc["assembly"], body, base, physics, f,
                                                    where=f"parts[{i}].assembly", file=file))
        with_assembly.append(body)
    parts = tuple(with_assembly)
    return Scene(name=session["name"], units=units, physics=physics, parts=parts, base=base,
                 hand_from_base=hand_from_base, environment=environment,
                 part_index={b.name: i for i, b in enumerate(parts)},
                 tools=_tools(session.get("tools", []), physics, f, file=file,
                              taken={b.name for b in (*parts, *environment)}
                              | ({base.name} if base is not None else set())),
                 base_fixed=base_fixed)


def _tools(docs: list, physics: Physics, length_factor: float, *, file: str,
           taken: set[str]) -> tuple[Tool, ...]:
    """The session's tools, sorted by name; each name is a device of the tracker stream, and
    none is the name of a hand, the head, another tool or a body (``taken``): an event's
    ``hand`` and ``part`` would be ambiguous."""
    tools: list[Tool] = []
    for i, doc in enumerate(docs):
        name = doc["name"]
        if name in HAND_DEVICES or name == BOTH_HANDS or name in taken \
                or any(t.name == name for t in tools):
            raise SessionError(f"tool name {name!r} is taken (by another tool, a part, the "
                               f"base, an environment object, or one of "
                               f"{', '.join((*HAND_DEVICES, BOTH_HANDS))})", file=file,
                               field=f"tools[{i}].name")
        radius = doc.get("grab_radius")
        tools.append(Tool(name, float(doc["max_mass_kg"]),
                          physics.grab_radius if radius is None
                          else float(radius) * length_factor))
    return tuple(sorted(tools, key=lambda t: t.name))
