"""A contact battery: parts leaving the base never pass into it, and come to rest somewhere
that holds them.

A helper's battery of 96 scenarios (2026-12-07; 71 passed before the flight grace of
5c4d091, 92 after) ported here: the scenes are built in ``_contact_battery`` (a pin sliding
up out of its bore, a sleeve off its shaft, a block let go against a wall, under a shelf or
off a plate's edge; tilted, turning, the base carried or jittering), each run in-process,
and the part's depth into the base and the table measured with exact solids, independent
of the simulator's meshes and fcl (``_contact_battery.measure``).

Short by default (CI): 24 representative scenarios. ``VADE_STRESS=full python -m pytest -q
-m stress`` runs all 96. The 2 known failures are strict xfails naming the gap documented
in docs/DEVELOPMENT.md ("Known gaps", first item): fixing one turns its xfail into a
failure, to be unmarked.
"""

from __future__ import annotations

import math

import pytest

import _contact_battery as cb
from conftest import run_records
from strategies import FULL

pytestmark = pytest.mark.stress

MM = 1e-3
RESTING = ("ONBASESTATIC", "ONBASESLIDE", "STATIC")

# The CI subset: each family's cases that fly (leave the base) and land in different places,
# the knife-edge reproductions of the bugs 5c4d091 fixed, and every known failure.
SHORT = {
    "1a_pin_up_out_sideways_c010_vx150_v430",        # flies, lands on the plate beside the boss
    "1a_pin_up_out_sideways_c005_vx100_v410",        # flies, lands on the boss's top
    "1c_pin_up_out_noisy_base_c010_s4_v420",         # the held base jittering 0.3 mm
    "1b_pin_pop_tilted_c010_roll20_v440",            # leans on the rim
    "1b_pin_pop_tilted_c005_roll35_v430",            # falls past the boss to the table
    "1d_pin_tiny_exit_tilted_c010_roll20_peak0.02",  # the engineer's bug, reproduced
    "1d_pin_tiny_exit_base_moves_c010_vx50_peak0.02",
    "1d_pin_tiny_exit_vertical_c010_peak0.02",
    "6_pin_half_out_tilt12_d0.5_w60_c010",
    "6_pin_half_out_tilt11_d1.5_w-120_c010",
    "6b_pin_half_in_no_constraint_tilt0.5_w120_c010",
    "6b_pin_half_in_no_constraint_tilt-0.5_w-120_c010",
    "6c_pin_half_in_tight_tolerance_tilt0.5_w60_c010",
    "2_block_wall_rest",
    "2_block_wall_w_into_plus60",
    "2_block_graze_wall_turning",
    "2_block_wall_noise_seed9",
    "3_shaft_slide_off_tilted25",
    "3b_sleeve_tiny_exit_c010_roll25_peak0.02",      # went through the whole shaft before
    "3b_sleeve_tiny_exit_nominal_roll10_peak0.1",
    "4_plane_block_edge_golden",
    "4_plane_block_edge_fast45",
    "5_under_overhang_w30",
    "5_leaning_wall_roll35",
}

_GAP = "docs/DEVELOPMENT.md, Known gaps: contact in flight is a sequence of grazes: "
KNOWN = {
    "4_plane_block_edge_golden": _GAP + "a block sliding off a plate's edge dips 0.4-0.5 mm "
    "into the plate's top for a frame as it tips (it left that face at distance 0)",
    "4_plane_block_edge_fast45": _GAP + "a block sliding off a plate's edge dips 0.4-0.5 mm "
    "into the plate's top for a frame as it tips (it left that face at distance 0)",
}

# Knife-edge scenarios tuned to the frame timing (``cb.peak_at_frame_end``) that, today,
# never leave their constraint: the pin or sleeve slides back down it. They guard the slide,
# not the flight; the others of their families must leave the base, or they test nothing.
STAYS_ON = {
    "1d_pin_tiny_exit_tilted_c005_roll5_peak0.02",
    "1d_pin_tiny_exit_tilted_c005_roll20_peak0.02",
    "1d_pin_tiny_exit_tilted_c005_roll35_peak0.02",
    "3b_sleeve_tiny_exit_nominal_roll10_peak0.02",
    "3b_sleeve_tiny_exit_nominal_roll25_peak0.02",
}


def scenarios(*prefixes: str) -> list:
    """The family's scenarios to run (all with VADE_STRESS=full), the known failures
    marked as strict xfails."""
    return [pytest.param(name, id=name, marks=[pytest.mark.xfail(strict=True,
                                                                 reason=KNOWN[name])]
                         if name in KNOWN else [])
            for name in cb.family(prefixes) if FULL or name in SHORT]


def run(name: str) -> cb.Outcome:
    doc = cb.SCENARIOS[name]()
    return cb.measure(doc, run_records(doc))


def assert_sound(o: cb.Outcome) -> None:
    """What every scenario must do.

    Never into the base or the table deeper than the contact tolerance (0.1 mm: within it
    a part counts as touching; test_contact_edges holds a pin to it in the boss) plus the
    tessellation slack: the meshes of round solids are polygons with their vertices on the
    circle, so an exact round surface lies up to r (1 - cos(pi/sections)) outside the mesh
    (0.058 mm for the boss, 0.024 mm the pin, 0.12 mm the sleeve's outside). The measure
    is of the exact solids; the bugs it caught went 0.4-9.8 mm deep.
    Never hanging in the air (INSPACE 0.5 s moving less than 2 mm relative to the base), not
    still flying at the end, and at rest within twice the tolerance of something (the
    reach of "touching" as a part leaves) that holds it up: moved down 0.5 mm it would go
    at least 0.05 mm into a face below it, which a vertical wall is not. Leaning (its
    lowest points held by nothing: there is no tipping) is allowed."""
    tol = o.contact_tolerance
    bound = tol + o.slack_base + o.slack_part
    assert o.max_pen_base <= bound, (
        f"{o.max_pen_base / MM:.3f} mm into the base at t = {o.max_pen_base_t:.3f} s "
        f"(bound {bound / MM:.3f} mm; {o.pen_at_release / MM:.3f} mm as let go); {o.causes}")
    assert o.max_pen_table <= tol + o.slack_part, f"{o.max_pen_table / MM:.3f} mm into the table"
    assert o.hang_t is None, f"hangs in the air from t = {o.hang_t:.2f} s; {o.causes}"
    assert o.mode in RESTING, f"ends {o.mode}; {o.causes}"
    assert o.gap <= 2 * tol, f"rests {o.gap / MM:.3f} mm from everything"
    assert o.held_up is not False, f"rests on nothing below it (held by a wall); {o.causes}"


def _upright_deg(o: cb.Outcome) -> float:
    return math.degrees(math.acos(min(1.0, abs(o.in_base[2, 2]))))


def _lowest_above(o: cb.Outcome, z: float) -> float:
    """How far (m) its lowest point lies above the base's plane z (base axes)."""
    return float(o.points_in_base[:, 2].min()) - z


def _off_axis(o: cb.Outcome, x: float, y: float) -> float:
    return math.hypot(o.in_base[0, 3] - x, o.in_base[1, 3] - y)


@pytest.mark.parametrize("name", scenarios("1a_", "1c_"))
def test_a_pin_sliding_up_off_its_bore_under_a_moving_base_stays_out_of_the_boss(name):
    """The bracket held in the left hand and carried +x at 0.05-0.15 m/s (``1a``) or still
    with 0.3 mm of tracker noise (``1c``); the pin let go on its axis 8 mm down the bore
    moving up it at 0.40-0.43 m/s. Those that slide off the bore's end fly on +x relative
    to the boss (the base stops): the bore's wall or rim stops or deflects them, and they
    end on their constraint in the bore, on the boss's top, the plate or the table; never
    inside the boss's material."""
    assert_sound(run(name))


@pytest.mark.parametrize("name", scenarios("1b_"))
def test_a_pin_popping_out_of_a_tilted_bore_falls_back_outside_the_boss(name):
    """The bracket fixed, rolled 20 or 35 deg; the pin let go 8 mm down the bore moving up
    it at 0.385-0.44 m/s. It slides up, pops 0-3 mm past the end and falls back at an angle
    to the bore (gravity across its axis): onto the downhill rim (where it may lean: no
    tipping), back onto its constraint, or off the boss to the table; never through the
    boss."""
    assert_sound(run(name))


@pytest.mark.parametrize("name", scenarios("1d_"))
def test_a_pin_just_clearing_its_bore_falls_back_down_it(name):
    """The pin slides up to rest 0.02-0.1 mm past the bore's mouth at a frame's end, so it
    leaves its constraint with no speed, never clear of the bore's wall; the bore upright,
    rolled 5-35 deg, or the held base carried sideways and stopped as it leaves. The wall
    stops any sideways drift: it falls back down the bore, onto its constraint, to the
    bore's bottom (the plate's top, base z 5 mm), upright and on the axis within the
    clearance. (Before 5c4d091 it fell through the wall and rested 7 mm off the axis
    inside the boss.)"""
    o = run(name)
    assert_sound(o)
    assert o.mode in ("ONBASESTATIC", "ONBASESLIDE"), o.causes
    if name not in STAYS_ON:
        assert "slid_off_base" in o.causes, f"no longer leaves the bore: {o.causes}"
        assert o.causes[o.causes.index("slid_off_base") + 1] == "landed_on_constraint", o.causes
    pin_r = 4.9 if "_c010_" in name else 4.95
    tol = o.contact_tolerance
    assert 0.0 <= _lowest_above(o, 5 * MM) <= tol + 1e-6   # on the bore's bottom
    assert _off_axis(o, 30 * MM, 0.0) <= (5 - pin_r) * MM + tol
    assert _upright_deg(o) < 1.0


@pytest.mark.parametrize("name", scenarios("6_"))
def test_a_pin_let_go_tilted_in_the_bores_mouth_never_enters_its_wall(name):
    """The bracket fixed upright; the pin let go tilted 11-15 deg (beyond the constraint's
    10 deg), its lowest point 0.5-1.5 mm down the mouth, 0.05 mm from the wall, the hand
    turning its lower end into the wall at up to 120 deg/s. It rests where it is let go or
    leans on the rim (no tipping: it would drop ~1 mm and wedge), or falls off the boss;
    its lower end never goes into the bore's wall."""
    assert_sound(run(name))


@pytest.mark.parametrize("name", scenarios("6b_", "6c_"))
def test_a_pin_let_go_turning_in_a_bore_it_is_not_snapped_into_falls_to_the_bottom(name):
    """The pin 10 mm down the bore, tilted 0.3-0.5 deg (it fits: the clearance allows
    ~1 deg), with no constraint (``6b``) or one whose 0.2 deg tolerance does not recognise
    the tilt (``6c``), let go with the hand turning its lower end into the wall at 30-120
    deg/s. The wall stops the turn; it falls down the bore to its bottom on the plate
    (base z 5 mm), nearly upright, on the axis within the clearance. (Before 5c4d091 it
    turned on to 3-11 deg through the wall and rested inside the boss.)"""
    o = run(name)
    assert_sound(o)
    assert 0.0 <= _lowest_above(o, 5 * MM) <= o.contact_tolerance + 1e-6, \
        f"its end {_lowest_above(o, 5 * MM) / MM:.3f} mm above the bore's bottom"
    assert _off_axis(o, 30 * MM, 0.0) <= 0.5 * MM
    assert _upright_deg(o) < 1.0


@pytest.mark.parametrize("name", scenarios("2_"))
def test_a_block_let_go_against_a_wall_falls_along_it_onto_the_plate(name):
    """``plane_block_wall``'s block (no constraint) let go 0.05 mm from the wall, 20 mm
    above the plate: at rest, turning at 20-60 deg/s (a tracker's rotation noise over a few
    frames), with tracker noise, or 10 mm off moving into the wall at 0.1 m/s and turning.
    A wall cannot hold it: it falls along the wall (stopped by it, never into it) and
    rests on the plate, within the contact tolerance of its top."""
    o = run(name)
    assert_sound(o)
    assert o.mode == "ONBASESTATIC" and o.causes[-1] == "landed_on_base", o.causes
    assert o.plate_gap <= o.contact_tolerance + 1e-6, f"{o.plate_gap / MM:.3f} mm off the plate"


@pytest.mark.parametrize("name", scenarios("3_", "4_"))
def test_a_part_sliding_off_the_base_falls_to_the_table(name):
    """``shaft_slide_off`` (the golden, its shaft tilted 10 or 25 deg, the sleeve's bore
    nominal or 0.1 mm wider): the sleeve slides up and off the shaft's end; ``plane_block_
    edge`` (and its base tilted to 45 deg in 0.4 s): the block slides over the plate's
    edge. Each falls to the table and rests on it (STATIC), never passing into the shaft,
    the block or the plate. A nominal fit leaves the shaft at distance 0, which must not
    stop it there."""
    o = run(name)
    assert_sound(o)
    assert o.mode == "STATIC" and o.causes[-1] == "hit_environment", o.causes
    assert o.table_gap <= o.contact_tolerance + 1e-6


@pytest.mark.parametrize("name", scenarios("3b_"))
def test_a_sleeve_just_clearing_its_shaft_falls_back_onto_it(name):
    """``shaft_placed``'s base held rolled 10 or 25 deg; the sleeve (0.1 mm radial
    clearance, or nominal) let go on the shaft moving up it, to rest 0.02-0.1 mm past the
    shaft's top at a frame's end, and falls back at an angle. The shaft stops its sideways
    drift: it lands back on the shaft and ends around it, on the axis within the clearance.
    (Before 5c4d091 it drifted through the whole shaft and lay 18-49 mm off the axis.)"""
    o = run(name)
    assert_sound(o)
    if name not in STAYS_ON:
        assert "slid_off_base" in o.causes, f"no longer leaves the shaft: {o.causes}"
    clearance = (10.1 - 10.0) * MM if "_c010_" in name else 0.0
    assert o.mode in ("ONBASESTATIC", "ONBASESLIDE"), o.causes
    assert _off_axis(o, 0.0, 0.0) <= clearance + o.contact_tolerance


@pytest.mark.parametrize("name", scenarios("5_"))
def test_a_block_let_go_under_a_shelf_or_a_leaning_wall_falls_to_the_plate(name):
    """The block let go at rest 0.05 mm under a shelf reaching over the plate (still or
    turning at 30 deg/s), or touching only a wall that leans over the plate (rolled 20 or
    35 deg): neither can hold it up. It falls and rests on the plate (ONBASESTATIC), within
    the contact tolerance of its top; never into the shelf, wall or plate, never hanging."""
    o = run(name)
    assert_sound(o)
    assert o.mode == "ONBASESTATIC" and o.causes[-1] == "landed_on_base", o.causes
    assert o.plate_gap <= o.contact_tolerance + 1e-6, f"{o.plate_gap / MM:.3f} mm off the plate"


def test_the_short_battery_is_a_subset_of_the_full_one():
    """The CI subset and the lists of known failures and of scenarios that stay on their
    constraint name real scenarios (a renamed one would silently drop out), and the full
    battery is the helper's 96."""
    assert SHORT <= set(cb.SCENARIOS) and set(KNOWN) <= SHORT and STAYS_ON <= set(cb.SCENARIOS)
    assert len(cb.SCENARIOS) == 96


def test_the_tessellation_slack_is_a_polygons_distance_inside_its_circle():
    """The penetration bound's slack: the boss's r 12 mm in 32 sections has its flats
    12 (1 - cos(pi/32)) = 0.0578 mm inside the circle; a box has none; 48 sections by
    default."""
    boss = {"type": "tube", "radius": 12, "inner_radius": 5, "height": 20, "sections": 32}
    assert cb.tessellation_slack(boss, 1e-3) == pytest.approx(0.0578e-3, abs=1e-7)
    assert cb.tessellation_slack({"type": "box", "size": [1, 1, 1]}, 1.0) == 0.0
    assert cb.tessellation_slack({"type": "cylinder", "radius": 1.0, "height": 1.0}, 1.0) == \
        pytest.approx(1 - math.cos(math.pi / 48))
