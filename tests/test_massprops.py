"""The CAD mass-property report parser, on reports whose numbers are known independently."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import trimesh

from conftest import make_session
from vade_replay.errors import SessionError
from vade_replay.massprops import parse_creo_report

REPORT = """\
VOLUME = {volume:.7e} MM^3
SURFACE AREA = 1.7000000e+04 MM^2
DENSITY = 7.8500000e-06 KILOGRAM / MM^3
MASS = {mass:.9e} KILOGRAM

CENTER OF GRAVITY with respect to _PRT0001 coordinate frame:
X   Y   Z   {cx:.9e}  {cy:.9e}  {cz:.9e}  MM

INERTIA with respect to _PRT0001 coordinate frame:  (KILOGRAM * MM^2)

INERTIA TENSOR:
Ixx Ixy Ixz   9.9e+02 0.0e+00 0.0e+00
Iyx Iyy Iyz   0.0e+00 9.9e+02 0.0e+00
Izx Izy Izz   0.0e+00 0.0e+00 9.9e+02

INERTIA at CENTER OF GRAVITY with respect to _PRT0001 coordinate frame:  (KILOGRAM * MM^2)

INERTIA TENSOR:
Ixx Ixy Ixz  {i[0][0]:.9e} {i[0][1]:.9e} {i[0][2]:.9e}
Iyx Iyy Iyz  {i[1][0]:.9e} {i[1][1]:.9e} {i[1][2]:.9e}
Izx Izy Izz  {i[2][0]:.9e} {i[2][1]:.9e} {i[2][2]:.9e}

PRINCIPAL MOMENTS OF INERTIA:  (KILOGRAM * MM^2)
I1  I2  I3   1.0e+00  2.0e+00  3.0e+00
"""


def _rotated_box():
    """A 100 x 50 x 20 mm steel box turned 30 degrees about z and moved: known by trimesh."""
    box = trimesh.creation.box(extents=[100.0, 50.0, 20.0])
    box.apply_transform(trimesh.transformations.rotation_matrix(np.radians(30), [0, 0, 1]))
    box.apply_translation([10.0, -5.0, 7.0])
    box.density = 7.85e-6  # kg / mm^3
    return box


def _report(box, *, products_sign="tensor") -> str:
    inertia = np.array(box.moment_inertia)
    if products_sign == "products":
        inertia = np.where(np.eye(3, dtype=bool), inertia, -inertia)
    cx, cy, cz = box.center_mass
    return REPORT.format(volume=box.volume, mass=box.mass, cx=cx, cy=cy, cz=cz, i=inertia)


def test_report_in_mm_and_kg_matches_the_geometry():
    box = _rotated_box()
    props = parse_creo_report(_report(box), file="box.m_p")
    assert props.mass_kg == pytest.approx(0.785, rel=1e-9)  # 100 * 50 * 20 mm^3 of steel
    assert np.allclose(props.center_of_mass, np.array([10.0, -5.0, 7.0]) * 1e-3, atol=1e-12)
    inertia = np.array(props.inertia_cm)
    # trimesh's tensor in kg mm^2, converted to kg m^2; the off-diagonals are not zero.
    assert np.allclose(inertia, np.array(box.moment_inertia) * 1e-6, rtol=1e-8, atol=1e-15)
    assert abs(inertia[0, 1]) > 1e-4
    # The closed form of the box about its own axes: m (b^2 + c^2) / 12 etc.
    moments = np.sort(np.linalg.eigvalsh(inertia))
    m = 0.785
    expected = np.sort([m * (0.05**2 + 0.02**2) / 12, m * (0.1**2 + 0.02**2) / 12,
                        m * (0.1**2 + 0.05**2) / 12])
    assert np.allclose(moments, expected, rtol=1e-8)


def test_products_sign_convention():
    box = _rotated_box()
    tensor = parse_creo_report(_report(box), file="a.m_p")
    products = parse_creo_report(_report(box, products_sign="products"), file="b.m_p",
                                 products_sign="products")
    assert np.allclose(tensor.inertia_cm, products.inertia_cm, rtol=1e-12)
    # Read with the wrong convention the off-diagonals flip sign.
    wrong = parse_creo_report(_report(box, products_sign="products"), file="c.m_p")
    assert np.allclose(np.array(wrong.inertia_cm)[0, 1], -np.array(tensor.inertia_cm)[0, 1])


@pytest.mark.parametrize("edit, field", [
    (lambda r: r.replace("MASS =", "WEIGHT ="), "MASS"),
    (lambda r: r.replace("KILOGRAM * MM^2)\n\nINERTIA TENSOR:\nIxx Ixy Ixz  ", "KILOGRAM * MM^2)\n\nINERTIA TENSOR:\nIxx Ixy Ixz  -"), "INERTIA"),
    (lambda r: r.replace("MM\n\nINERTIA with", "FURLONG\n\nINERTIA with"), "CENTER OF GRAVITY"),
])
def test_bad_reports_name_the_field(edit, field):
    with pytest.raises(SessionError) as info:
        parse_creo_report(edit(_report(_rotated_box())), file="bad.m_p")
    assert "bad.m_p" in str(info.value)
    assert field in str(info.value)


def test_session_reads_a_report_and_rejects_an_open_mesh_without_one():
    box = _rotated_box()
    open_mesh = trimesh.creation.box(extents=[0.1, 0.05, 0.02])
    open_mesh.update_faces(np.arange(len(open_mesh.faces)) != 0)  # one triangle missing
    stl = open_mesh.export(file_type="stl")
    part = {"name": "p", "shape": {"type": "mesh", "file": "p.stl"},
            "pose": {"position": [0, 0, 1.0]}}
    doc = {"format": "vade-session/1", "name": "t", "parts": [dict(part, density=2700)],
           "tracker": {"duration_s": 0.1, "devices": {"right_hand": [{"t": 0}]}}}
    with pytest.raises(SessionError) as info:
        make_session(doc, {"p.stl": stl}).build_scene()
    assert "watertight" in str(info.value) and "parts[0]" in str(info.value)
    doc["parts"] = [dict(part, mass_properties={"file": "p.m_p"})]
    scene = make_session(json.loads(json.dumps(doc)),
                         {"p.stl": stl, "p.m_p": _report(box).encode()}).build_scene()
    assert scene.parts[0].mass_kg == pytest.approx(0.785, rel=1e-9)


@pytest.mark.parametrize("flip, needle", [
    (lambda faces: np.where((np.arange(len(faces)) % 3 == 0)[:, None], faces[:, ::-1], faces),
     "not wound consistently"),
    (lambda faces: faces[:, ::-1], "normals are inverted")])
def test_a_closed_mesh_wound_wrongly_is_refused_not_given_a_wrong_mass(flip, needle):
    """A CAD export with some (or all) faces wound inward is still watertight; its volume
    came out as the difference of the two sides (a third of the mass for every third face
    flipped) or negative ("mass must be positive", blaming the density). Both are named on
    the shape; the same mesh wound right gives the mass of its volume."""
    box = trimesh.creation.box(extents=[0.1, 0.05, 0.02])
    part = {"name": "p", "shape": {"type": "mesh", "file": "p.stl"}, "density": 2700,
            "pose": {"position": [0, 0, 1.0]}}
    doc = {"format": "vade-session/1", "name": "t", "parts": [part],
           "tracker": {"duration_s": 0.1, "devices": {"right_hand": [{"t": 0}]}}}
    bad = trimesh.Trimesh(box.vertices, flip(box.faces), process=False)
    assert bad.is_watertight
    with pytest.raises(SessionError) as info:
        make_session(doc, {"p.stl": bad.export(file_type="stl")}).build_scene()
    assert needle in str(info.value) and "parts[0].shape" in str(info.value)
    scene = make_session(doc, {"p.stl": box.export(file_type="stl")}).build_scene()
    # (STL holds float32 vertices: the volume to ~1e-7.)
    assert scene.parts[0].mass_kg == pytest.approx(2700 * 0.1 * 0.05 * 0.02, rel=1e-6)


def test_unit_and_base_mass_errors_say_what_to_change():
    """A mesh file whose size says it is in another unit points at the shape's own
    ``units``; an open base mesh with a density says its mass is not used (leaving the
    density out was the way, and no message said so)."""
    box = trimesh.creation.box(extents=[0.06, 0.04, 0.02])  # metres: 0.06 mm read as mm
    stl = box.export(file_type="stl")
    part = {"name": "p", "shape": {"type": "mesh", "file": "p.stl"}, "density": 2700,
            "pose": {"position": [0, 0, 1000.0]}}
    doc = {"format": "vade-session/1", "name": "t", "units": "mm", "parts": [part],
           "tracker": {"duration_s": 0.1, "devices": {"right_hand": [{"t": 0}]}}}
    with pytest.raises(SessionError) as info:
        make_session(doc, {"p.stl": stl}).build_scene()
    assert "mm across" in str(info.value) and "shape's \"units\"" in str(info.value)
    part["shape"]["units"] = "m"
    assert make_session(doc, {"p.stl": stl}).build_scene().parts[0].mass_kg > 0
    open_mesh = trimesh.creation.box(extents=[100, 50, 20])
    open_mesh.update_faces(np.arange(len(open_mesh.faces)) != 0)
    doc["base"] = {"name": "b", "shape": {"type": "mesh", "file": "b.stl"}, "density": 2700}
    files = {"p.stl": stl, "b.stl": open_mesh.export(file_type="stl")}
    with pytest.raises(SessionError) as info:
        make_session(doc, files).build_scene()
    assert "leave out the base's density" in str(info.value)
    del doc["base"]["density"]
    assert make_session(doc, files).build_scene().base is not None


@pytest.mark.parametrize("data, needle", [
    (b"solid nothing\nendsolid nothing\n", "holds no triangles"),
    # A binary STL that says it holds 1000 triangles and stops after 10 bytes of them.
    (b"\x00" * 80 + (1000).to_bytes(4, "little") + b"\x01" * 10, "cannot read mesh")])
def test_an_unreadable_mesh_is_named_from_the_session_that_names_it(data, needle):
    """The error names the session file, the field and the mesh as the session writes it
    (it used to name the mesh alone, as a path relative to the session's folder)."""
    part = {"name": "p", "shape": {"type": "mesh", "file": "../meshes/p.stl"},
            "density": 2700, "pose": {"position": [0, 0, 1.0]}}
    doc = {"format": "vade-session/1", "name": "t", "parts": [part],
           "tracker": {"duration_s": 0.1, "devices": {"right_hand": [{"t": 0}]}}}
    with pytest.raises(SessionError) as info:
        make_session(doc, {"../meshes/p.stl": data}).build_scene()
    text = str(info.value)
    assert needle in text and "'../meshes/p.stl'" in text and "parts[0].shape.file" in text
    assert info.value.file == make_session(doc, {"../meshes/p.stl": data}).source


# --- Principal axes (spatial.symmetric_eigen: Jacobi rotations, the same bits anywhere) ---

def _check_eigen(matrix, values, axes, tol):
    a = np.array(matrix, dtype=np.float64)
    v = np.array(axes)
    scale = max(1e-300, float(np.max(np.abs(a))))
    assert list(values) == sorted(values)
    assert np.max(np.abs(v.T @ v - np.eye(3))) <= 4e-16 * 4          # orthonormal
    assert np.linalg.det(v) > 0.0                                     # a rotation
    assert np.max(np.abs(v @ np.diag(values) @ v.T - a)) <= tol * scale  # A = V D V^T


def test_symmetric_eigen_matches_lapack_on_random_inertias():
    from vade_replay import spatial as sp
    rng = np.random.default_rng(7)
    for k in range(3000):
        q = np.linalg.qr(rng.normal(size=(3, 3)))[0]
        # Spread, nearly equal and exactly equal moments, over ten decades.
        d = [rng.uniform(1e-6, 1.0, 3), np.array([1.0, 1.0, rng.uniform(0.1, 2.0)]),
             10.0 ** rng.uniform(-10.0, 0.0, 3), 1.0 + 1e-12 * rng.normal(size=3)][k % 4]
        a = q @ np.diag(d) @ q.T
        a = ((a + a.T) / 2).tolist()
        values, axes = sp.symmetric_eigen(a)
        reference = np.linalg.eigvalsh(np.array(a))
        assert np.max(np.abs(np.array(values) - reference)) <= 4e-15 * np.max(reference)
        _check_eigen(a, values, axes, 4e-15)


def test_symmetric_eigen_closed_forms():
    from vade_replay import spatial as sp
    # A diagonal tensor: its own values, sorted; the axes a signed permutation.
    values, axes = sp.symmetric_eigen(((2.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 3.0)))
    assert values == (1.0, 2.0, 3.0)
    assert sorted(abs(x) for row in axes for x in row) == [0.0] * 6 + [1.0] * 3
    assert np.array(axes)[:, 0].tolist() == [0.0, 1.0, 0.0]
    # A solid cylinder (m 0.3 kg, r 0.02 m, h 0.1 m) turned 30 deg about x: m r^2 / 2 about
    # its axis, m (3 r^2 + h^2) / 12 across it twice, and the axis found where it was turned.
    m, r, h = 0.3, 0.02, 0.1
    axial, across = m * r * r / 2, m * (3 * r * r + h * h) / 12
    c, s = math.cos(math.radians(30)), math.sin(math.radians(30))
    rot = np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    tensor = (rot @ np.diag([across, across, axial]) @ rot.T).tolist()
    values, axes = sp.symmetric_eigen(tensor)
    assert values[0] == pytest.approx(axial, rel=1e-14)
    assert values[1] == pytest.approx(across, rel=1e-14)
    assert values[2] == pytest.approx(across, rel=1e-14)
    assert abs(float(np.array(axes)[:, 0] @ rot[:, 2])) == pytest.approx(1.0, abs=1e-15)
    _check_eigen(tensor, values, axes, 4e-16)
    # Nothing to rotate: the identity, and a zero matrix.
    assert sp.symmetric_eigen(np.eye(3).tolist()) == ((1.0, 1.0, 1.0), tuple(
        tuple(row) for row in np.eye(3).tolist()))
    assert sp.symmetric_eigen(np.zeros((3, 3)).tolist())[0] == (0.0, 0.0, 0.0)
