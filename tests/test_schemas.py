"""Schemas in schemas/: one per event class, and every recorded message validates."""

from __future__ import annotations

import dataclasses
import json

import jsonschema
import pytest

from conftest import RECORDINGS, ROOT
from vade_replay import codec, events
from vade_replay.recording import Recording
from vade_replay.session import load_schema

SCHEMAS = ROOT / "schemas"


def test_event_classes_and_schema_files_are_one_to_one():
    files = {p.name.removesuffix(".schema.json") for p in (SCHEMAS / "events").glob("*.json")}
    assert files == set(events.REGISTRY)
    for kind, cls in events.REGISTRY.items():
        schema = json.loads((SCHEMAS / "events" / f"{kind}.schema.json").read_text())
        fields = {f.name for f in dataclasses.fields(cls)} | {"kind", "version"}
        assert set(schema["properties"]) == fields, kind
        assert schema["properties"]["version"] == {"const": cls.VERSION}


def test_every_channel_has_a_schema_file():
    for topic, (_, schema_file) in codec.CHANNELS.items():
        assert (SCHEMAS / schema_file).is_file(), topic
        jsonschema.Draft202012Validator.check_schema(load_schema(schema_file))


@pytest.mark.parametrize("golden", sorted(RECORDINGS.glob("*.mcap")), ids=lambda p: p.stem)
def test_recorded_messages_validate(golden):
    validators = {topic: jsonschema.Draft202012Validator(load_schema(f))
                  for topic, (_, f) in codec.CHANNELS.items()}
    seen = set()
    for frame in Recording(golden).frames():
        validators[codec.TRACKER_TOPIC].validate(json.loads(codec.dumps(
            codec.encode_tracker(frame.inputs))))
        for topic, data in frame.derived:
            validators[topic].validate(json.loads(data))
            seen.add(topic)
    assert {codec.PARTS_TOPIC, codec.FOXGLOVE_TOPIC, "/events/ModeChanged"} <= seen


@pytest.mark.parametrize("session", sorted(RECORDINGS.glob("*.json")), ids=lambda p: p.stem)
def test_shipped_sessions_validate(session):
    jsonschema.Draft202012Validator(load_schema("session.schema.json")).validate(
        json.loads(session.read_text()))


def test_old_event_versions_are_upcast():
    old = {"kind": "ModeChanged", "version": 1, "frame": 3, "part": "p", "cause": "grabbed",
           "from_mode": "STATIC", "to_mode": "INHAND"}
    event = events.from_dict(old)
    assert event == events.ModeChanged(3, "p", "grabbed", "STATIC", "INHAND")
    with pytest.raises(Exception, match="newer"):
        events.from_dict(dict(old, version=99))


def _as_dict_reference(event: events.Event) -> dict:
    """The message of an event as ``to_dict`` wrote it before it was written out flat:
    ``dataclasses.asdict``, its kind and version, tuples as lists."""
    data = dataclasses.asdict(event)
    data["kind"] = event.kind
    data["version"] = event.VERSION
    return {k: list(v) if isinstance(v, tuple) else v for k, v in data.items()}


def test_event_messages_are_asdicts_with_kind_and_version():
    # Every event of every golden, and one of each kind with -0.0, tiny and large numbers:
    # the bytes written are those of the asdict reference, and read back to the event.
    samples = [events.ModeChanged(3, "p", "grabbed", "STATIC", "INHAND"),
               events.PartGrabbed(1, "gear", "caught", "both_hands"),
               events.GrabRefused(2, "", "nothing_in_reach", "left_hand"),
               events.PartReleased(4, "pin", "released", "right_hand", (-0.0, 1e-300, 2.5e17),
                                   (0.1, -3.0, 7e-05)),
               events.ContactMade(5, "box", "hit_environment", "table", 2**63 + 5)]
    assert {type(e) for e in samples} == set(events.REGISTRY.values())
    for golden in sorted(RECORDINGS.glob("*.mcap")):
        for frame in Recording(golden).frames():
            samples += [codec.decode_event(topic, data) for topic, data in frame.derived
                        if topic.startswith(codec.EVENT_TOPIC_PREFIX)]
    assert len(samples) > 50
    for event in samples:
        written = events.to_dict(event)
        assert written == _as_dict_reference(event)
        assert list(written) == list(_as_dict_reference(event))  # the same key order too
        assert codec.dumps(written) == codec.dumps(_as_dict_reference(event))
        assert events.from_dict(written) == event
