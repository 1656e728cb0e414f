"""The source distribution holds everything a wheel built from it compiles.

``python -m build`` makes an sdist, then a wheel from that sdist alone: a C source missing
from the sdist fails that build (``FileNotFoundError`` in ``setup.py``), as a fresh check
of the eleventh session's C extension found.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tarfile
from pathlib import Path

import pytest

from vade_replay import native

ROOT = Path(__file__).resolve().parents[1]


def _checkout_copy(to: Path) -> None:
    """The files of this checkout as git sees them (tracked, and untracked but not ignored),
    without what an install left: setuptools reuses an ``*.egg-info`` it finds (its
    SOURCES.txt lists what an earlier sdist held), which would hide a file left out."""
    listed = subprocess.run(["git", "ls-files", "-z", "--cached", "--others",
                             "--exclude-standard"], cwd=ROOT, capture_output=True)
    if listed.returncode != 0:
        pytest.skip("not a git checkout")
    for name in filter(None, listed.stdout.decode().split("\0")):
        source = ROOT / name
        if source.is_file():
            target = to / name
            target.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(source, target)


def test_the_sdist_holds_every_source_the_build_compiles(tmp_path):
    pytest.importorskip("setuptools")
    source = tmp_path / "checkout"
    _checkout_copy(source)
    # A build's record of what it compiled, as a compiled checkout has it: not to be shipped.
    (source / native.BUILT_FROM).write_text("SOURCES = {}\n", encoding="utf-8")
    env = dict(os.environ)
    # (ext_modules() compiles nothing for sdist; the switch only keeps it so if that changes.)
    env[native.PURE_ENV] = "1"
    done = subprocess.run([sys.executable, "setup.py", "-q", "sdist", "--dist-dir",
                           str(tmp_path / "dist"), "--formats=gztar"], cwd=source, env=env,
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    (archive,) = (tmp_path / "dist").glob("*.tar.gz")
    with tarfile.open(archive) as tar:
        names = {name.split("/", 1)[1] for name in tar.getnames() if "/" in name}
    needed = {*native.MODULES, *native.C_EXTENSIONS.values(), "setup.py", "pyproject.toml",
              "vade_replay/native.py"}
    assert needed <= names, sorted(needed - names)
    # A checkout's record of what it compiled is not the sdist's to ship.
    assert native.BUILT_FROM not in names
