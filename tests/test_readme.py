"""The README's commands are real: CI runs its test command, and its synopsis parses."""

from __future__ import annotations

import re
import shlex

import pytest

from conftest import ROOT

README = (ROOT / "README.md").read_text()


def _blocks() -> list[str]:
    return re.findall(r"```bash\n(.*?)```", README, flags=re.S)


def test_readme_opens_with_the_two_commands():
    blocks = _blocks()
    demo, tests = blocks[0].strip(), blocks[1].strip()
    assert "pip install" in demo and "vade-record" in demo and "vade-replay" in demo
    assert "--rerun" in demo
    assert "pip install" in tests and "pytest" in tests
    ci = (ROOT / ".ci" / "run").read_text()
    assert tests in ci, "CI must run the README's test command"


def _synopsis_lines():
    lines = []
    for block in _blocks():
        for line in block.splitlines():
            line = line.split("#")[0].strip()
            if line.startswith("vade-"):
                lines.append(line)
    assert len(lines) >= 5
    return lines


@pytest.mark.parametrize("line", _synopsis_lines())
def test_synopsis_line_parses(line):
    from vade_replay.cli import bench, goldens, record, replay

    parsers = {"vade-record": record._parser, "vade-replay": replay._parser,
               "vade-goldens": goldens._parser, "vade-bench": bench._parser}
    words = shlex.split(line.replace("[", "").replace("]", "").replace("...", ""))
    words = [w for w in words if w != "NAME"]
    parsers[words[0]]().parse_args(words[1:])
