"""A part's ``mass`` (kg): its density or mass_properties then only spread it. Held to the
closed form of a box and to the same part's density-made properties; a what-if
``--set parts.PART.mass`` for any part, also one whose mass comes from a CAD report."""

from __future__ import annotations

import json

import pytest

from conftest import RECORDINGS, run_cli
from vade_replay import session as session_mod
from vade_replay.recording import Recording
from vade_replay.replay import record, replay


def _scene(doc):
    return session_mod.parse(json.dumps(doc).encode(), {}, source="s.json").build_scene()


def _peg(doc):
    return next(p for p in _scene(doc).parts if p.name == "peg")


def _doc():
    return json.loads((RECORDINGS / "drop_on_table.json").read_text())


def test_a_box_given_only_its_mass_has_the_closed_form_inertia():
    """Peg 0.04 x 0.04 x 0.08 m, 0.5 kg, no density: I = m (b^2 + c^2) / 12 about each axis
    through the centre (to 1e-12 relative; trimesh sums the box's triangles)."""
    doc = _doc()
    peg = doc["parts"][0]
    del peg["density"]
    peg["mass"] = 0.5
    body = _peg(doc)
    assert body.mass_kg == 0.5
    a, b, c = 0.04, 0.04, 0.08
    expected = (0.5 * (b * b + c * c) / 12, 0.5 * (a * a + c * c) / 12, 0.5 * (a * a + b * b) / 12)
    for k in range(3):
        assert body.inertia_cm[k][k] == pytest.approx(expected[k], rel=1e-12)
    assert body.center_of_mass == pytest.approx((0.0, 0.0, 0.0), abs=1e-15)


def test_a_mass_scales_what_the_density_gives_and_keeps_its_centre():
    doc = _doc()
    made = _peg(doc)  # 2700 kg/m^3: 0.3456 kg
    doc["parts"][0]["mass"] = 2.0
    scaled = _peg(doc)
    k = 2.0 / made.mass_kg
    assert scaled.mass_kg == 2.0 and scaled.center_of_mass == made.center_of_mass
    for row, base in zip(scaled.inertia_cm, made.inertia_cm):
        assert row == pytest.approx([x * k for x in base], rel=1e-14)


def test_a_mass_scales_the_numbers_of_mass_properties():
    doc = _doc()
    peg = doc["parts"][0]
    del peg["density"]
    peg["mass_properties"] = {"mass": 1.0, "center_of_mass": [0.0, 0.0, 0.01],
                              "inertia": [[2e-4, 0, 0], [0, 3e-4, 0], [0, 0, 4e-4]]}
    peg["mass"] = 3.0
    body = _peg(doc)
    assert body.mass_kg == 3.0 and body.center_of_mass == pytest.approx((0.0, 0.0, 0.01))
    assert sorted(body.principal_moments) == pytest.approx([6e-4, 9e-4, 12e-4], rel=1e-12)


def test_a_part_with_neither_density_nor_mass_is_refused_naming_both():
    doc = _doc()
    del doc["parts"][0]["density"]
    with pytest.raises(session_mod.SessionError, match="its density, its mass or its "
                                                       "mass_properties"):
        _scene(doc)


def _grams(tmp_path):
    """The peg given 250 for its mass (grams meant): the document and its file."""
    doc = _doc()
    del doc["parts"][0]["density"]
    doc["parts"][0]["mass"] = 250
    path = tmp_path / "grams.json"
    path.write_text(json.dumps(doc))
    return doc, path


def test_a_mass_in_grams_is_warned_of_by_the_density_it_makes(tmp_path):
    """250 written for 250 g: 250 kg in the peg's 128 cm^3 is no solid's density."""
    doc, path = _grams(tmp_path)
    summary = record(session_mod.load(path), tmp_path / "grams.mcap")
    (warning,) = [w for w in summary.warnings if ".mass" in w]
    assert warning.startswith("parts[0].mass (part 'peg'): 250 kg in 128 cm^3 is 1.95e+06 kg/m^3")
    # Kept in the recording: a replay of it tells them again (a reviewer of a colleague's
    # file saw only "match").
    assert Recording(tmp_path / "grams.mcap").warnings == []  # (read with the frames)
    replayed = replay(Recording(tmp_path / "grams.mcap"))
    assert replayed.match and replayed.recorded_warnings == summary.warnings
    result = run_cli("vade-replay", str(tmp_path / "grams.mcap"))
    assert f"warning: {tmp_path / 'grams.mcap'}: when recorded: {warning}" in result.stderr
    doc["parts"][0]["mass"] = 0.25
    path.write_text(json.dumps(doc))
    assert not [w for w in record(session_mod.load(path), tmp_path / "g.mcap").warnings
                if ".mass" in w]


def test_a_what_if_of_a_parts_mass_asks_would_it_still_be_lifted(tmp_path):
    """The recorded 0.35 kg peg made 25 kg (over both hands' 15 kg): refused at the grab.
    A part whose mass comes from mass_properties takes the same what-if (it could not be
    given a density); one given a mass refuses a density what-if, naming the key to use."""
    summary = replay(Recording(RECORDINGS / "drop_on_table.mcap"),
                     overrides={"parts.peg.mass": "25"}).to_dict()
    assert summary["analysis"]["refused_grabs"] == {"too_heavy_for_two_hands": 1}
    assert summary["masses_kg"] == {"peg": 25.0}
    doc = _doc()
    peg = doc["parts"][0]
    del peg["density"]
    peg["mass_properties"] = {"mass": 0.35, "center_of_mass": [0, 0, 0],
                              "inertia": [[2e-4, 0, 0], [0, 2e-4, 0], [0, 0, 1e-4]]}
    path = tmp_path / "cad.json"
    path.write_text(json.dumps(doc))
    out = tmp_path / "cad.mcap"
    record(session_mod.load(path), out)
    heavy = replay(Recording(out), overrides={"parts.peg.mass": "25"}).to_dict()
    assert heavy["analysis"]["refused_grabs"] == {"too_heavy_for_two_hands": 1}
    result = run_cli("vade-replay", str(out), "--set", "parts.peg.density=5000")
    assert result.returncode == 2 and "change parts.peg.mass (kg)" in result.stderr
    peg["mass"] = 0.35
    path.write_text(json.dumps(doc))
    record(session_mod.load(path), out)
    result = run_cli("vade-replay", str(out), "--set", "parts.peg.density=5000")
    assert result.returncode == 2 and "change parts.peg.mass" in result.stderr


def test_set_values_may_carry_a_mass_or_length_unit_and_an_unknown_one_is_named():
    """``12g`` and ``0.012kg`` are one mass; ``5cm`` a length like ``50mm``; ``3ft`` is
    refused naming the units there are, and a unit of the wrong kind names the key."""
    from vade_replay.errors import ConfigError
    from vade_replay.replay import _in_session_units
    assert _in_session_units("parts.peg.mass", "12g", "mm") == repr(0.012)
    assert _in_session_units("parts.peg.mass", "0.012 kg", "m") == repr(0.012)
    assert _in_session_units("physics.grab_radius", "5cm", "mm") == repr(50.0)
    assert _in_session_units("physics.grab_radius", "5cm", "m") == repr(0.05)
    assert _in_session_units("physics.grab_radius", "1e-3", "m") == "1e-3"
    with pytest.raises(ConfigError, match="unknown unit 'ft' .lengths: m, mm, in, cm, um, "
                                          "µm, nm; masses: kg, g"):
        _in_session_units("parts.peg.mass", "3ft", "m")
    with pytest.raises(ConfigError, match="has a mass unit, and this is not a mass"):
        _in_session_units("physics.grab_radius", "3g", "m")
    # An angle's field takes an angle unit, as --tolerance does (a researcher's trial:
    # 35deg was refused); its number is in degrees, the field's unit.
    key = "parts.sleeve.constraints.bore_on_shaft.tolerance.angle_deg"
    assert float(_in_session_units(key, "35deg", "mm")) == 35.0
    assert float(_in_session_units(key, "30deg", "m")) == 30.0  # (not 29.999999999999996)
    assert float(_in_session_units(key, "0.5rad", "m")) == pytest.approx(28.64788975654116)
    with pytest.raises(ConfigError, match="has an angle unit, and this is not an angle"):
        _in_session_units("physics.grab_radius", "2deg", "m")
    with pytest.raises(ConfigError, match="a length in the session's units, a mass in kg, "
                                          "an angle in degrees"):
        _in_session_units(key, "3ft", "m")
    summary = replay(Recording(RECORDINGS / "drop_on_table.mcap"),
                     overrides={"parts.peg.mass": "25000g"}).to_dict()
    assert summary["masses_kg"] == {"peg": 25.0}


def _warnings(doc):
    from vade_replay.collision import CollisionWorld
    from vade_replay.replay import mass_warnings
    session = session_mod.parse(json.dumps(doc).encode(), {}, source="s.json")
    scene = session.build_scene()
    assert CollisionWorld(scene)  # (builds, as a recording would)
    return mass_warnings(scene, session.doc)


def test_mass_properties_in_other_units_are_warned_of():
    """The peg (0.04 x 0.04 x 0.08 m) given CAD numbers: right, nothing; its mass in grams
    (345.6 for 0.3456 kg), its inertia in kg mm^2 (a million times), a moment no body of
    that shape can have, and a centre of mass outside it: each said."""
    doc = _doc()
    peg = doc["parts"][0]
    del peg["density"]
    m = 0.3456
    right = {"mass": m, "center_of_mass": [0, 0, 0],
             "inertia": [[m * (0.04**2 + 0.08**2) / 12, 0, 0], [0, m * (0.04**2 + 0.08**2) / 12, 0],
                         [0, 0, m * (0.04**2 + 0.04**2) / 12]]}
    peg["mass_properties"] = right
    assert _warnings(doc) == []
    peg["mass_properties"] = dict(right, mass=345.6)
    (grams,) = _warnings(doc)
    assert grams.startswith("parts[0].mass_properties: 345.6 kg in 128 cm^3 is 2.7e+06 kg/m^3")
    peg["mass_properties"] = dict(right, inertia=[[x * 1e-6 for x in row]
                                                  for row in right["inertia"]])
    (units,) = _warnings(doc)
    assert "its inertia is 1e-06 times that of its shape" in units
    peg["mass_properties"] = dict(right, inertia=[[x * 20 for x in row]
                                                  for row in right["inertia"]])
    (too_big,) = _warnings(doc)
    assert "more than any body of this shape and mass can have" in too_big
    peg["mass_properties"] = dict(right, center_of_mass=[0, 0, 0.05])
    (outside,) = _warnings(doc)
    assert "the centre of mass (0, 0, 50) mm in the part's axes lies outside" in outside


def test_a_what_if_of_a_mass_in_grams_is_warned_of():
    """``--set parts.peg.mass=350`` (grams meant) of the 0.35 kg peg: the what-if says its
    density is no solid's, as vade-record would; 0.35 says nothing."""
    heavy = replay(Recording(RECORDINGS / "drop_on_table.mcap"),
                   overrides={"parts.peg.mass": "350"})
    # Named by its --set key, not the session's index (an engineer read that as another part).
    assert [w for w in heavy.warnings if w.startswith("parts.peg.mass: 350 kg in 128 cm^3")]
    assert replay(Recording(RECORDINGS / "drop_on_table.mcap"),
                  overrides={"parts.peg.mass": "0.35"}).warnings == []


def test_vade_record_tells_of_refused_grabs_and_parts_never_placed(tmp_path):
    """An engineer's trial: the summary line said "3 transitions" where a grab was refused
    as too heavy; now a line says so, naming the part, and another names the parts with a
    final pose that the run never placed."""
    doc = _doc()
    doc["parts"][0]["mass"] = 25.0
    path = tmp_path / "heavy.json"
    path.write_text(json.dumps(doc))
    out = run_cli("vade-record", str(path), "-o", str(tmp_path / "heavy.mcap")).stdout
    assert "refused grabs: too_heavy_for_two_hands 1 (peg)" in out
    missed = run_cli("vade-record", str(RECORDINGS / "shaft_release_missed.json"), "-o",
                     str(tmp_path / "missed.mcap")).stdout
    assert "never placed: sleeve (of 1 with a final pose)" in missed
    placed = run_cli("vade-record", str(RECORDINGS / "shaft_placed.json"), "-o",
                     str(tmp_path / "placed.mcap")).stdout
    assert "never placed" not in placed and "refused" not in placed


def test_a_regenerated_recording_keeps_the_warnings_and_the_early_stop(tmp_path):
    """``vade-replay X -o Y``: Y keeps what X's run warned of (and a what-if's own), and
    that X's run stopped early; it lost both (a review)."""
    _, path = _grams(tmp_path)
    made = record(session_mod.load(path), tmp_path / "grams.mcap")
    again = replay(Recording(tmp_path / "grams.mcap"), out=tmp_path / "again.mcap")
    assert again.match
    copy = Recording(tmp_path / "again.mcap")
    list(copy.frames())
    assert copy.warnings == made.warnings and not copy.truncated
    from conftest import interrupted_recording
    assert interrupted_recording(session_mod.load(path), tmp_path / "cut.mcap", 30) == 130
    replay(Recording(tmp_path / "cut.mcap.partial"), out=tmp_path / "cut_again.mcap")
    cut = Recording(tmp_path / "cut_again.mcap")
    assert len(list(cut.frames())) == 30 and cut.truncated and cut.stopped == "interrupted"


def test_the_outcome_lines_leave_out_empty_hands_and_parts_placed_from_the_start():
    """A hand closing on nothing is no refused grab a design answers; a part that starts
    in its final pose (PLACED throughout, never placed by the run) is not "never placed"
    (a review)."""
    from cli.record import _outcome_lines
    doc = {"parts": [{"name": "housing", "assembly": {"final_pose": {}}},
                     {"name": "sleeve", "assembly": {"final_pose": {}}}]}
    analysis = {"refused_grabs": {"nothing_in_reach": 2},
                "parts": {"housing": {"placed_at_s": None, "refused_grabs": 0,
                                      "time_in_state_s": {"PLACED": 4.0}},
                          "sleeve": {"placed_at_s": None, "refused_grabs": 0,
                                     "time_in_state_s": {"STATIC": 4.0}}}}
    # Not a refused grab; where no part was grabbed at all, said as what it is (an
    # engineer's trial: a hand scripted above its part).
    assert _outcome_lines(analysis, doc) == [
        "no part was grabbed: a hand closed 2 times with nothing in reach (a part's box "
        "within physics.grab_radius of the hand; --events lists each)",
        "never placed: sleeve (of 2 with a final pose)"]
    analysis["parts"]["sleeve"]["grabs"] = 1
    assert _outcome_lines(analysis, doc) == ["never placed: sleeve (of 2 with a final pose)"]
    analysis["refused_grabs"]["too_heavy_for_one_hand"] = 1
    analysis["parts"]["sleeve"]["refused_grabs"] = 1
    assert _outcome_lines(analysis, doc)[0] == \
        "refused grabs: too_heavy_for_one_hand 1 (sleeve)"


@pytest.mark.parametrize("key, hint", [
    ("parts.peg.mas=1", "unknown field 'mas' of part 'peg' (a typo of 'mass'?)"),
    ("parts.peg.final_tolerance.distanc=1",
     "unknown field 'final_tolerance.distanc' of part 'peg' "
     "(a typo of 'final_tolerance.distance'?)"),
    ("parts.peg.constraints.pin.friction.static=0.5",
     "part 'peg' has no assembly (no constraints, no final pose)")])
def test_a_typo_in_a_part_s_field_is_named_as_one(key, hint):
    """A newcomer's trial: ``--set parts.peg.mas=1`` on a part with no constraints was told
    "part 'peg' has no assembly", though ``parts.peg.mass`` is any part's. An unknown
    field is said to be one, with the field it is nearest; a constraint's field on a part
    with none still says that."""
    result = run_cli("vade-replay", str(RECORDINGS / "drop_on_table.mcap"), "--set", key)
    assert result.returncode == 2 and result.stdout == ""
    assert result.stderr == f"error: --set {key.split('=')[0]}: {hint}" + (
        "" if "no assembly" in hint else "; a part's field is parts.PART.constraints.NAME."
        "FIELD=VALUE (FIELD: tolerance.distance, tolerance.angle_deg, friction.static, "
        "friction.dynamic, friction.rotational, friction.holding_torque) or "
        "parts.PART.FIELD=VALUE (FIELD: mass, density, final_tolerance.distance, "
        "final_tolerance.angle_deg)") + "\n"
