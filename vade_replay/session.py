"""Session files: read, validate against ``schemas/session.schema.json``, gather named files.

A ``Session`` holds the document and the bytes of every file it names, so the same object
comes from a file on disk or from a recording's attachments, and the scene built from
either is the same.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
import re
from dataclasses import dataclass
from importlib import metadata as importlib_metadata
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING, Iterator

from . import inputs
from .errors import SessionError, VadeError
from .frames import TrackerFrame
from .scene import UNIT_TO_M, Physics, Scene, build_scene

if TYPE_CHECKING:
    import jsonschema

# jsonschema is imported when a session is validated, not before: a replay of a recording
# whose session was validated when it was recorded (``validated_digest``) does without it,
# ~40 ms of a command's start.
_VALIDATOR_CLASS = "Draft202012Validator"


def _no_constants(name: str):
    raise ValueError(f"{name} is not a number a session can hold")


def strict_json(text: str | bytes):
    """JSON as the standard has it: NaN and Infinity are refused, not read as floats."""
    return json.loads(text, parse_constant=_no_constants)


def load_schema(name: str) -> dict:
    """A JSON Schema shipped in ``schemas/`` (installed as ``vade_replay.schemas``)."""
    ref = resources.files("vade_replay.schemas")
    for part in name.split("/"):
        ref = ref.joinpath(part)
    return json.loads(ref.read_text(encoding="utf-8"))


_VALIDATOR = None
_SCHEMA_DIGEST: str | None = None


def validated_digest(raw: bytes) -> str:
    """What a recording stores of a session it validated: SHA-256 over this version's
    session schema and the session's bytes. A file whose session bytes (and the schema)
    are unchanged since then need not be validated again: for a session of 200 parts,
    jsonschema takes about 100 ms, most of a replay's setup."""
    global _SCHEMA_DIGEST
    if _SCHEMA_DIGEST is None:
        # The validator too: another jsonschema might judge the same bytes otherwise.
        schema = json.dumps([load_schema("session.schema.json"),
                             importlib_metadata.version("jsonschema"),
                             _VALIDATOR_CLASS], sort_keys=True)
        _SCHEMA_DIGEST = hashlib.sha256(schema.encode()).hexdigest()
    return hashlib.sha256(_SCHEMA_DIGEST.encode() + b"\n" + raw).hexdigest()


def _validator() -> jsonschema.Draft202012Validator:
    global _VALIDATOR
    if _VALIDATOR is None:
        import jsonschema
        _VALIDATOR = getattr(jsonschema, _VALIDATOR_CLASS)(load_schema("session.schema.json"))
    return _VALIDATOR


_PHYSICS_VALIDATOR = None


def _physics_validator() -> jsonschema.Draft202012Validator:
    """The session schema's ``physics`` block on its own (it refers to nothing else in the
    schema; ``tests/test_session.py`` holds it to that)."""
    global _PHYSICS_VALIDATOR
    if _PHYSICS_VALIDATOR is None:
        import jsonschema
        schema = load_schema("session.schema.json")
        _PHYSICS_VALIDATOR = getattr(jsonschema, _VALIDATOR_CLASS)(
            {"$schema": schema["$schema"], **schema["properties"]["physics"]})
    return _PHYSICS_VALIDATOR


def _path(error: jsonschema.ValidationError, prefix: tuple = ()) -> str:
    out = ""
    for item in (*prefix, *error.absolute_path):
        out += f"[{item}]" if isinstance(item, int) else (f".{item}" if out else str(item))
    return out or "(top level)"


# A field in a list of named things: a user knows them by name, not by place.
_NAMED_ITEM = re.compile(r"(parts|environment|tools)\[(\d+)\]")
_ITEM_KIND = {"parts": "part", "environment": "environment object", "tools": "tool"}


def _item(field: str | None, doc: object) -> tuple[str, str] | None:
    """What ``field`` (``parts[3].shape``) is in, as (kind, name): ("part", "peg")."""
    match = _NAMED_ITEM.match(field or "")
    if match is None or not isinstance(doc, dict):
        return None
    items = doc.get(match.group(1))
    index = int(match.group(2))
    if not isinstance(items, list) or index >= len(items) or not isinstance(items[index], dict):
        return None
    name = items[index].get("name")
    if not isinstance(name, str) or not name:
        return None
    return _ITEM_KIND[match.group(1)], name


def named_item(field: str | None, doc: object) -> str | None:
    """The part, environment object or tool that ``field`` (``parts[3].shape``) is in, by
    the name the session gives it (``part 'peg'``), or None."""
    item = _item(field, doc)
    return None if item is None else f"{item[0]} {item[1]!r}"


_WARNED_FIELD = re.compile(r"((?:parts|environment|tools)\[\d+\][\w.\[\]]*):")


def name_warnings(lines: list[str], doc: object) -> list[str]:
    """Warnings that begin with a field (``parts[3].mass: ...``) with the part, environment
    object or tool it is in named after it (``named_item``) where the line does not name
    it already."""
    out = []
    for line in lines:
        match = _WARNED_FIELD.match(line)
        item = _item(match.group(1), doc) if match else None
        if match and item and not re.search(rf"(?<!\w){re.escape(item[1])}(?!\w)",
                                            line[match.end():]):
            line = f"{match.group(1)} ({item[0]} {item[1]!r}):{line[match.end():]}"
        out.append(line)
    return out


def _naming(exc: VadeError, doc: object) -> VadeError:
    """``exc`` with the part, environment object or tool its field is in named
    (``named_item``), its message made again."""
    if exc.item is None:
        exc.item = named_item(exc.field, doc)
        exc.args = (exc.describe(),)
    return exc


def validate(doc: object, *, file: str) -> None:
    """Raise ``SessionError`` naming the first bad field (and the part, environment object
    or tool it is in: ``named_item``)."""
    try:
        _first_error(_validator(), doc, file, ())
    except SessionError as exc:
        raise _naming(exc, doc) from None


def validate_physics(block: object, *, file: str) -> None:
    """``validate`` of a session's ``physics`` block alone (fields named ``physics.KEY``):
    what ``replay``'s ``--as-recorded`` holds restored physics to, without validating a
    session of hundreds of parts again."""
    _first_error(_physics_validator(), block, file, ("physics",))


def _first_error(validator, doc: object, file: str, prefix: tuple) -> None:
    errors = sorted(validator.iter_errors(doc), key=lambda e: (list(e.absolute_path), e.message))
    if errors:
        import jsonschema
        error = _branch_error(jsonschema.exceptions.best_match(errors))
        field = _path(error, prefix)
        if error.validator == "additionalProperties" and isinstance(error.instance, dict):
            # Name the unexpected key itself, and what would have been allowed.
            known = sorted(error.schema.get("properties", {}))
            extra = sorted(k for k in error.instance if k not in known)
            if extra:
                import difflib
                field = f"{field}.{extra[0]}" if field != "(top level)" else extra[0]
                # A typo of an allowed key ("densty"): name it before the whole list.
                close = difflib.get_close_matches(extra[0], known, n=1)
                hint = f" (a typo of {close[0]!r}?)" if close else ""
                raise SessionError(f"unknown field {extra[0]!r}{hint}; allowed: "
                                   f"{', '.join(known)}", file=file, field=field)
        message = error.message
        if isinstance(error.instance, bool) or error.instance is None:
            # The value as the user wrote it, JSON's true/false/null, not Python's repr (a
            # user's trial: "--set physics.gravity_scale_free=true" read "True is not of
            # type 'number'").
            message = message.replace(repr(error.instance), json.dumps(error.instance), 1)
        if error.validator == "not" and isinstance(error.validator_value, dict) \
                and list(error.validator_value) == ["required"]:
            # (It read "{...} should not be valid under {'required': ['xyzw', 'euler_deg']}".)
            message = (f"{' and '.join(error.validator_value['required'])} are both given: "
                       "give one")
        if error.validator == "oneOf" and not error.context and isinstance(error.instance, dict):
            # Valid under more than one alternative (a user's trial: a tracker with both csv
            # and devices read "{...the whole block...} is valid under each of ...").
            given = [schema["required"][0] for schema in error.validator_value
                     if isinstance(schema, dict) and schema.get("required")
                     and all(k in error.instance for k in schema["required"])]
            if len(given) > 1:
                message = f"{' and '.join(given)} are both given: give one"
        if error.validator == "required" and isinstance(error.instance, dict):
            # A typo of the required key ("radus" for "radius"): name the key written.
            import difflib
            missing = [k for k in error.validator_value if k not in error.instance]
            written = [k for k in error.instance if k not in error.validator_value]
            for key in missing:
                close = difflib.get_close_matches(key, written, n=1, cutoff=0.7)
                if close:
                    message += f" (is {close[0]!r} a typo of it?)"
                    break
        raise SessionError(message, file=file, field=field)


# A tracker block's keys that apply to keyframes alone, and to a tracker log alone
# (``csv_between`` is warned of on its own).
_KEYFRAMES_ONLY = ("rate_hz", "duration_s", "noise")
_LOG_ONLY = ("csv_units", "csv_time_unit", "csv_quaternion_order")


# Hands and the head in VR move about a metre or two from the origin: in a session in mm or
# inches, keyframe numbers all under this were most likely written in metres.
_METRES_LIKE = 3.0

# A keyframe session lasting this long past its last keyframe, and this many times its
# time, was most likely meant shorter (5000 for 5.0).
_IDLE_AFTER_S = 60.0
_IDLE_FACTOR = 10.0


# Physics lengths past these (in metres) are most likely written in another unit: a hand
# reaches for a part a few centimetres off, and contact is a fraction of a millimetre.
_LENGTHS_AT_MOST_M = {"grab_radius": 0.5, "contact_tolerance": 0.01}
_RECOGNISED_AT_LEAST_M = 1e-4


def _unlikely_lengths(doc: dict, units: str) -> list[str]:
    """Physics lengths, and tools' reach, too long for what they are once converted from
    the session's units (a user's trial: ``--set physics.grab_radius=15`` in a metre
    session, meant as 15 mm, grabbed from 15 m without a word)."""
    out = []
    f = UNIT_TO_M[units]
    given = [(f"physics.{key}", key, (doc.get("physics") or {}).get(key))
             for key in _LENGTHS_AT_MOST_M]
    given += [(f"tools[{i}].grab_radius", "grab_radius", tool.get("grab_radius"))
              for i, tool in enumerate(doc.get("tools") or [])]
    for field, key, value in given:
        if isinstance(value, (int, float)) and not isinstance(value, bool) \
                and float(value) * f > _LENGTHS_AT_MOST_M[key]:
            # (Not "meant as a smaller unit?": a --set value with its own unit, 60cm, is
            # warned of too; a researcher's trial read that as wrong.)
            what = "a hand reaches for a part a few centimetres off" \
                if key == "grab_radius" else "contact is a fraction of a millimetre"
            out.append(f"{field} is {float(value) * f:.4g} m, over "
                       f"{_LENGTHS_AT_MOST_M[key]:g} m: {what}; is it as meant? (a plain "
                       f"number is in the session's units, {units}; a --set value may "
                       "carry its own: 15mm)")
    # A constraint's recognition tolerance is how near a hand must let the part go: under a
    # tenth of a millimetre none does (an engineer's trial: a --set of 0.012 in a mm
    # session, meant as 12 mm, recognised nothing, "the recording is unchanged").
    for i, part in enumerate(doc.get("parts") or []):
        constraints = ((part.get("assembly") or {}).get("constraints") or []) \
            if isinstance(part, dict) else []
        for k, constraint in enumerate(constraints):
            value = ((constraint or {}).get("tolerance") or {}).get("distance")
            if isinstance(value, (int, float)) and not isinstance(value, bool) \
                    and 0.0 < float(value) * f < _RECOGNISED_AT_LEAST_M:
                out.append(f"parts[{i}].assembly.constraints[{k}].tolerance.distance is "
                           f"{float(value) * f * 1e3:.3g} mm: it is in the session's units "
                           f"({units}), and no hand lets a part go that near its constraint; "
                           "meant as a larger unit? (a --set value may carry its own: 12mm)")
    return out


# Densities of solids a part is made of, kg/m^3: from foams (~15) to tungsten (19,300).
_DENSITY_RANGE = (10.0, 25000.0)


def _unlikely_densities(doc: dict) -> list[str]:
    """A density outside any solid's: kg/mm^3 (7.85e-06 for steel) or g/cm^3 (7.85) for
    kg/m^3, whatever the session's length unit."""
    bodies = [("base", doc.get("base"))] + [
        (f"parts[{i}]", part) for i, part in enumerate(doc.get("parts") or [])]
    out = []
    lo, hi = _DENSITY_RANGE
    for where, body in bodies:
        if isinstance(body, dict) and "density" in body:
            rho = float(body["density"])
            if not lo <= rho <= hi:
                out.append(f"{where}.density: {rho:g} kg/m^3 is no solid's (steel is about "
                           "7850, aluminium 2700, ABS 1050); densities are in kg/m^3 "
                           "whatever the session's units")
    return out


def _friction_inverted(doc: dict) -> list[str]:
    """Dynamic friction above static (the session's, or a constraint's, each defaulting to
    the physics' and then to ``Physics``'): no material has it, and a part that slides
    slows to rest where static friction cannot hold it, and stays, sliding at no speed."""
    physics = doc.get("physics") or {}
    default = Physics()
    static = float(physics.get("friction_static", default.friction_static))
    dynamic = float(physics.get("friction_dynamic", default.friction_dynamic))
    why = ("no material has it: a part sliding on a slope between the two slows to rest, "
           "where static friction cannot hold it, and stays there sliding at no speed")
    out = []
    if dynamic > static:
        out.append(f"physics: friction_dynamic {dynamic:g} is above friction_static "
                   f"{static:g}; {why}")
    for i, part in enumerate(doc.get("parts") or []):
        for k, c in enumerate((part.get("assembly") or {}).get("constraints") or []):
            friction = c.get("friction") or {}
            if not friction:
                continue
            s_k = float(friction.get("static", static))
            d_k = float(friction.get("dynamic", dynamic))
            if d_k > s_k:
                out.append(f"parts[{i}].assembly.constraints[{k}].friction: dynamic {d_k:g} "
                           f"is above static {s_k:g}; {why}")
    return out


def _shared_constraint_names(doc: dict) -> list[str]:
    """Two constraints of one part under one name: events, release misses and ``--set``
    name a constraint by its name, so they cannot tell the two apart."""
    out = []
    for i, part in enumerate(doc.get("parts") or []):
        constraints = (part.get("assembly") or {}).get("constraints") or []
        names = [c.get("name", f"{c.get('type')}{k}") for k, c in enumerate(constraints)]
        for name in sorted({n for n in names if names.count(n) > 1}):
            out.append(f"parts[{i}].assembly.constraints: {names.count(name)} constraints of "
                       f"part {part.get('name')!r} are named {name!r}: reports and --set "
                       "name a constraint by its name, so give each its own")
    return out


def _shared_body_names(doc: dict) -> list[str]:
    """A part named as the base or an environment object, or two of those under one name: a
    part's rows in ``--poses`` and its events then mix with the other's under one name (a
    researcher's trial: a part named as its base, 181 base rows and 60 of the part's as
    one). Warned of, not refused, as shared constraint names are: a recording made so
    still replays."""
    bodies = ([("base", (doc.get("base") or {}).get("name"))] if doc.get("base") else [])
    bodies += [(f"environment[{i}]", item.get("name"))
               for i, item in enumerate(doc.get("environment") or [])]
    bodies += [(f"parts[{i}]", item.get("name")) for i, item in enumerate(doc.get("parts") or [])]
    out, first = [], {}
    for where, name in bodies:
        if name is None:
            continue
        if name in first and not (first[name].startswith("parts[")
                                  and where.startswith("parts[")):  # (parts: refused)
            other = "the base" if first[name] == "base" else first[name]
            out.append(f"{where}.name: {name!r} is also {other}'s name: their rows in "
                       "--poses and their events share it, so tables mix the two; give "
                       "each its own")
        first.setdefault(name, where)
    return out


# A quaternion given this far from norm 1 is most likely a slip (a typo, a component
# dropped, another order's numbers): it is read as its unit quaternion all the same.
_QUATERNION_NORM_SLIP = 1e-3


def _unnormalised_quaternions(doc: dict) -> list[str]:
    """Rotations (``xyzw``) anywhere in the session that are not unit quaternions: read as
    their unit quaternion without a word until a user's trial (``[0, 0, 0, 2]``); the first
    three."""
    out: list[str] = []

    def walk(value: object, where: str) -> None:
        if isinstance(value, dict):
            q = value.get("xyzw")
            if isinstance(q, list) and len(q) == 4 \
                    and all(isinstance(c, (int, float)) for c in q):
                norm = math.sqrt(sum(float(c) ** 2 for c in q))
                if norm > 0.0 and abs(norm - 1.0) > _QUATERNION_NORM_SLIP:
                    out.append(f"{where}.xyzw: {q} has norm {norm:.4g}, not 1: read as the "
                               "unit quaternion of its direction; a typo?")
            for key, item in value.items():
                walk(item, f"{where}.{key}" if where else key)
        elif isinstance(value, list):
            for k, item in enumerate(value):
                walk(item, f"{where}[{k}]")
    walk(doc, "")
    return out[:3]


def _unknown_body_keys(doc: dict) -> list[str]:
    """Keys of the base or an environment object that neither has (``fixd`` for ``fixed``:
    the base then rode the hand without a word). Their schema, unlike a part's, lets them
    carry others; making it strict would change its digest and refuse older recordings."""
    import difflib
    schema = load_schema("session.schema.json")
    body = set(schema["$defs"]["body"]["properties"])
    bodies = [("base", doc.get("base"), body | set(schema["properties"]["base"]["properties"]))]
    bodies += [(f"environment[{i}]", item, body)
               for i, item in enumerate(doc.get("environment") or [])]
    out = []
    for where, item, known in bodies:
        if not isinstance(item, dict):
            continue
        for key in sorted(set(item) - known):
            close = difflib.get_close_matches(key, sorted(known), n=1)
            out.append(f"{where}.{key}: not a field of the {where.split('[')[0]}, ignored"
                       + (f" (did you mean {close[0]!r}?)" if close else ""))
    return out


def _unknown_shape_keys(doc: dict) -> list[str]:
    """A shape's keys that no shape has (``sectons`` for ``sections``): the schema lets a
    shape carry others, so that a typo of an optional key would pass unnoticed."""
    import difflib
    known = set(load_schema("session.schema.json")["$defs"]["shape"]["properties"])
    out = []

    def walk(shape: object, where: str, child: bool) -> None:
        if not isinstance(shape, dict):
            return
        for key in sorted(shape):
            if key not in known and not (child and key == "pose"):
                close = difflib.get_close_matches(key, sorted(known), n=1)
                out.append(f"{where}.{key}: not a shape's field, ignored"
                           + (f" (did you mean {close[0]!r}?)" if close else ""))
        for i, item in enumerate(shape.get("children") or []):
            walk(item, f"{where}.children[{i}]", True)

    bodies = [("base", doc.get("base"))] + [
        (f"{group}[{i}]", body) for group in ("parts", "environment")
        for i, body in enumerate(doc.get(group) or [])]
    for where, body in bodies:
        if isinstance(body, dict):
            walk(body.get("shape"), f"{where}.shape", False)
    return out


def _branch_error(error):
    """For "not valid under any of the given schemas" (a ``oneOf`` or ``anyOf``), the error
    of the alternative the value was most likely meant as: the one whose first required key
    it has (a tracker with ``csv`` is a CSV log), then the one whose fields it uses most,
    then the one with the fewest errors."""
    while error.validator in ("oneOf", "anyOf") and error.context:
        branches: dict[int, list] = {}
        for sub in error.context:
            branches.setdefault(sub.schema_path[0], []).append(sub)
        instance = error.instance

        def fit(item):
            index, subs = item
            schema = error.schema[error.validator][index]
            names: set = set()
            required: list = []
            if isinstance(schema, dict):
                required = list(schema.get("required", []))
                names = set(schema.get("properties", {})) | set(required)
            if not isinstance(instance, dict):
                return (0, 0, len(subs))
            # The first required key names the alternative (devices or csv, file or mass).
            named = bool(required) and required[0] in instance
            return (-named, -sum(k in names for k in instance), len(subs))

        _, subs = min(branches.items(), key=fit)
        import jsonschema
        error = jsonschema.exceptions.best_match(subs)
    return error


# The first bytes of every MCAP file.
MCAP_MAGIC = b"\x89MCAP"


def referenced_files(doc: dict) -> dict[str, str]:
    """Every file a session names (relative to the session file) -> the field that names it."""
    found: dict[str, str] = {}

    def walk(value, where: str) -> None:
        # Into containers only: a 200-part session has thousands of numbers, and a path
        # string made for each cost milliseconds of every replay's setup.
        if isinstance(value, dict):
            for key in sorted(value):
                item = value[key]
                if key in ("file", "csv") and isinstance(item, str):
                    found.setdefault(item, f"{where}.{key}")
                elif isinstance(item, (dict, list)):
                    walk(item, f"{where}.{key}")
        elif isinstance(value, list):
            for index, item in enumerate(value):
                if isinstance(item, (dict, list)):
                    walk(item, f"{where}[{index}]")

    for key in ("parts", "base", "environment", "tracker"):
        if key in doc:
            walk(doc[key], key)
    return dict(sorted(found.items()))


@dataclass(frozen=True)
class Session:
    """A validated session document and the bytes of the files it names."""

    doc: dict
    files: dict[str, bytes]
    source: str  # where it came from, for messages
    raw: bytes   # the session file's own bytes, attached to recordings as they are
    # Not validated again: a recording's digest said these bytes were (parse(validated=)).
    trusted: bool = False
    # Physics values (SI) that stand for this version's defaults where the session gives
    # none: those a recording was made with (``replay.as_made``).
    physics_defaults: dict | None = None

    @property
    def name(self) -> str:
        return self.doc["name"]

    def build_scene(self) -> Scene:
        try:
            return build_scene(self.doc, self.files, file=self.source,
                               physics_defaults=self.physics_defaults)
        except VadeError as exc:
            _naming(exc, self.doc)
            raise
        except Exception:
            if self.trusted:
                # A digest that vouched for bytes it was not made from (forged, not a
                # mistake): the schema names the bad field instead of a traceback.
                validate(self.doc, file=self.source)
            raise

    def warnings(self) -> list[str]:
        """What is allowed but most likely a slip: gravity far from Earth's once converted
        from the session's units, keyframes after the session ends."""
        out = []
        units = self.doc.get("units", "m")
        gravity = (self.doc.get("physics") or {}).get("gravity")
        if gravity is not None:
            g = math.sqrt(sum(float(v) ** 2 for v in gravity)) * UNIT_TO_M[units]
            if g != 0.0 and not 1.0 <= g <= 30.0:
                out.append(f"physics.gravity is {g:.4g} m/s^2: it is in the session's units "
                           f"({units}/s^2), so Earth's is {9.81 / UNIT_TO_M[units]:g}")
            # (A user's trial: a sign slipped, and the only word was a part "still falling
            # ... past everything in the scene", having risen.)
            if float(gravity[2]) > 0.0 and float(gravity[2]) >= max(abs(float(v))
                                                                    for v in gravity):
                out.append(f"physics.gravity {list(gravity)} points up: the scene's up is +z "
                           "(the table under the parts, the head above them), so parts fall "
                           "upward; meant its z negative?")
        given = self.doc.get("physics") or {}
        defaults = Physics()
        one = float(given.get("one_hand_max_mass_kg", defaults.one_hand_max_mass_kg))
        two = float(given.get("two_hand_max_mass_kg", defaults.two_hand_max_mass_kg))
        if 0.0 < two < one and "two_hand_max_mass_kg" not in given:
            # (A review: one hand's raised alone was told "swapped?" of a key not written.)
            out.append(f"physics.one_hand_max_mass_kg ({one:g} kg) is over "
                       f"two_hand_max_mass_kg's default ({two:g} kg): no part is lifted by "
                       "two hands; raise two_hand_max_mass_kg too?")
        elif 0.0 < two < one:
            # (One hand's limit says no part is lifted by two hands; under it, most likely
            # the two are swapped: a user's trial.)
            out.append(f"physics.two_hand_max_mass_kg ({two:g} kg) is under "
                       f"one_hand_max_mass_kg ({one:g} kg): two hands lift nothing one hand "
                       "cannot, so no part is lifted by two; swapped? (equal says so "
                       "plainly)")
        out += _unlikely_lengths(self.doc, units)
        out += _unknown_shape_keys(self.doc)
        out += _shared_constraint_names(self.doc)
        out += _shared_body_names(self.doc)
        out += _unlikely_densities(self.doc)
        out += _friction_inverted(self.doc)
        out += _unknown_body_keys(self.doc)
        out += _unnormalised_quaternions(self.doc)
        tracker = self.doc["tracker"]
        if "csv_between" in tracker and "csv" not in tracker:
            out.append("tracker.csv_between applies to a tracker log (tracker.csv); "
                       "keyframes are always interpolated: it does nothing here")
        # (A user's trial: noise added to a real log for a robustness study, and duration_s
        # to trim it, made the same run as the log alone without a word.)
        for key in _KEYFRAMES_ONLY if "csv" in tracker else _LOG_ONLY:
            if key in tracker:
                out.append(f"tracker.{key} applies to "
                           + ("keyframes (tracker.devices); a tracker log (tracker.csv) is "
                              "read as it is, every sample at its own time: it does nothing "
                              "here" if "csv" in tracker else
                              "a tracker log (tracker.csv): it does nothing with keyframes"))
        devices = tracker.get("devices")
        if devices is not None and not devices:
            out.append("tracker.devices is empty: no hand, head or tool moves, so nothing is "
                       "grabbed")
        elif devices is not None:
            # (A researcher's trial: a tool with no stream of its name recorded without a
            # word; it never moves, so it never takes a part.)
            for i, tool in enumerate(self.doc.get("tools") or []):
                if tool.get("name") not in devices:
                    out.append(f"tools[{i}]: no tracker stream is named {tool.get('name')!r} "
                               "(tracker.devices): the tool never moves, so it never takes "
                               "a part")
        if "csv" in tracker:
            gap = self._csv_sample_gap_s()
            unit = tracker.get("csv_time_unit", "s")
            if gap is not None and not 1e-4 <= gap <= 1.0:
                out.append(f"tracker.csv_time_unit: the log's frames are {gap:.4g} s apart "
                           f"read as {unit}; a tracker samples every few ms: is the unit "
                           "right?")
        reaches = {name: [max(abs(float(c)) for c in kf["position"]) for kf in frames
                          if "position" in kf]
                   for name, frames in sorted((tracker.get("devices") or {}).items())}
        reach = [r for rs in reaches.values() for r in rs]
        if units != "m" and reach and max(reach) < _METRES_LIKE:
            out.append(f"tracker.devices: every keyframe position is under {_METRES_LIKE:g} "
                       f"{units} from the origin (at most {max(reach):g}): written in metres? "
                       f"they are read in the session's units ({units})")
        elif units != "m":
            # One device written in metres among the others in the session's unit.
            for name, rs in reaches.items():
                if rs and 0.0 < max(rs) < _METRES_LIKE:
                    out.append(f"tracker.devices.{name}: every keyframe position is under "
                               f"{_METRES_LIKE:g} {units} from the origin (at most "
                               f"{max(rs):g}), unlike the other devices': written in metres? "
                               f"they are read in the session's units ({units})")
                elif units == "mm" and rs and max(rs) >= 10.0 * _METRES_LIKE:
                    # One keyframe written in metres among the device's others (in a mm
                    # session only: 3 in, 76 mm, is a place a hand may be).
                    frames = [kf for kf in tracker["devices"][name] if "position" in kf]
                    odd = [(k, kf) for k, (kf, r) in enumerate(zip(frames, rs))
                           if 0.0 < r < _METRES_LIKE]
                    for k, kf in odd[:3]:
                        out.append(f"tracker.devices.{name}: the keyframe at t = {kf['t']:g} s "
                                   f"is {max(abs(float(c)) for c in kf['position']):g} {units} "
                                   f"from the origin, the others up to {max(rs):g}: written "
                                   f"in metres? it is read in the session's units ({units})")
        end = float(tracker.get("duration_s", 0.0))
        for name, frames in sorted((tracker.get("devices") or {}).items()):
            late = [kf["t"] for kf in frames if kf["t"] > end]
            if "duration_s" in tracker and late:
                out.append(f"tracker.devices.{name}: {len(late)} keyframe"
                           f"{'s' if len(late) > 1 else ''} after duration_s ({end:g} s), "
                           f"never reached (first at t = {late[0]:g} s)")
        last = max((float(kf["t"]) for frames in (tracker.get("devices") or {}).values()
                    for kf in frames), default=None)
        if "duration_s" in tracker and last is not None \
                and end > max(_IDLE_AFTER_S, _IDLE_FACTOR * last):
            # (An engineer's trial: 5000 meant 5.0 made 300,001 frames, 29 MB, without a word.)
            rate = float(tracker.get("rate_hz", 60))
            out.append(f"tracker.duration_s: {end:g} s runs {end - last:g} s past the last "
                       f"keyframe (t = {last:g} s), {int(end * rate) + 1:,} frames of nothing "
                       "moving but what falls: meant less?")
        return name_warnings(out, self.doc)

    def _csv_sample_gap_s(self) -> float | None:
        """The median time between a device's samples in the first rows of a CSV log (each
        device apart: a log may stamp its devices microseconds apart), in the log's time
        unit read as seconds; None if too few rows can be read (recording names a bad one)."""
        import csv
        import io
        tracker = self.doc["tracker"]
        scale = 1e-9 * inputs.TIME_TO_NS.get(tracker.get("csv_time_unit", "s"), 10**9)
        rows = csv.reader(io.StringIO(self.files[tracker["csv"]].decode("utf-8-sig",
                                                                       errors="replace")))
        header = [h.strip().lower() for h in next(rows, [])]
        if "time" not in header or "device" not in header:
            return None
        at, of = header.index("time"), header.index("device")
        last: dict[str, float] = {}
        gaps = []
        for row in itertools.islice(rows, 2000):
            try:
                t, device = float(row[at]), row[of].strip()
            except (IndexError, ValueError):
                continue
            if device in last and t > last[device]:
                gaps.append((t - last[device]) * scale)
            last[device] = t
        gaps.sort()
        return gaps[len(gaps) // 2] if gaps else None

    def file_named(self, name: str) -> str:
        """Where a file the session names is, for messages: beside a session file
        (``study/p01/log.csv``, as typed), or inside the recording that stores the session
        (``run.mcap:files/log.csv``). (A user's trial: a bad row of ``study/p01/log.csv`` was
        named ``log.csv: line 51``.)"""
        head, colon, tail = self.source.rpartition(":")
        if colon and tail == "session.json":  # (``Recording``'s source for its session)
            return f"{head}:files/{name}"
        return str(Path(self.source).parent / name)

    def frame_count(self) -> int | None:
        """How many frames ``tracker_frames`` makes, where that is known before reading
        them (keyframes; not a CSV log): a progress bar's total."""
        tracker = self.doc["tracker"]
        return None if "csv" in tracker else inputs.keyframe_frame_count(tracker)

    def tracker_frames(self) -> Iterator[TrackerFrame]:
        """The tracker stream to record (keyframes resampled, or the CSV log)."""
        tracker = self.doc["tracker"]
        units = self.doc.get("units", "m")
        if "csv" in tracker:
            name = tracker["csv"]
            return inputs.from_csv(self.files[name], file=self.file_named(name),
                                   units=tracker.get("csv_units", units),
                                   time_unit=tracker.get("csv_time_unit", "s"),
                                   quaternion_order=tracker["csv_quaternion_order"],
                                   known=inputs.devices(self.doc),
                                   between=tracker.get("csv_between", "interpolate"))
        return inputs.from_keyframes(tracker, units, file=self.source,
                                     known=inputs.devices(self.doc))


def parse(raw: bytes, files: dict[str, bytes], *, source: str,
          validated: str | None = None) -> Session:
    """A Session from the session file's bytes and the named files' bytes. ``validated``:
    the ``validated_digest`` a recording stored; when it matches, schema validation is
    skipped (the bytes are the ones validated then, against the same schema)."""
    try:
        doc = strict_json(raw.decode("utf-8-sig"))  # (a BOM: Windows editors)
    except (UnicodeDecodeError, ValueError) as exc:
        raise SessionError(f"not valid JSON: {exc}", file=source) from None
    trusted = validated is not None and validated == validated_digest(raw)
    if not trusted:
        validate(doc, file=source)
    for name, where in referenced_files(doc).items():
        if name not in files:
            raise SessionError(f"file {name!r} is missing", file=source, field=where,
                               item=named_item(where, doc))
    return Session(doc, files, source, raw, trusted)


def _looks_like_a_tracker_log(raw: bytes) -> bool:
    """A CSV whose first line is a header naming a tracker log's columns (time, device)."""
    head = raw[:4096].decode("utf-8-sig", errors="replace").lstrip().split("\n", 1)[0]
    names = {cell.strip().strip('"').lower() for cell in re.split(r"[,;\t]", head)}
    return len(names) >= 3 and "device" in names \
        and any(n == "t" or n.startswith("time") for n in names)


def load(path: str | Path) -> Session:
    """Read and validate a session file and every file it names, relative to it."""
    path = Path(path)
    if path.is_dir():
        raise SessionError("is a folder, not a session file", file=str(path))
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise SessionError(f"cannot read session file: {exc.strerror}", file=str(path)) from None
    if not raw.strip():
        raise SessionError("an empty file, not a session", file=str(path))
    if raw.startswith(MCAP_MAGIC):
        raise SessionError("this is a recording (MCAP), not a session file: replay it with "
                           "vade-replay", file=str(path))
    try:
        doc = strict_json(raw.decode("utf-8-sig"))  # (a BOM: Windows editors)
    except (UnicodeDecodeError, ValueError) as exc:
        if _looks_like_a_tracker_log(raw):
            # (A researcher's trial: a log given for its session read "not valid JSON".)
            raise SessionError("this is a tracker log (CSV), not a session file: name it in "
                               'a session file ("tracker": {"csv": "' + path.name + '", ...}) '
                               "and record that session", file=str(path)) from None
        raise SessionError(f"not valid JSON: {exc}", file=str(path)) from None
    validate(doc, file=str(path))
    files = {}
    for name, where in referenced_files(doc).items():
        target = path.parent / name
        try:
            files[name] = target.read_bytes()
        except OSError as exc:
            raise SessionError(f"cannot read {target}: {exc.strerror}", file=str(path),
                               field=where, item=named_item(where, doc)) from None
    return Session(doc, files, str(path), raw)
