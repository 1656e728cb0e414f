"""Which per-frame modules run compiled, and the switch back to their Python sources.

``pip install`` compiles the modules in ``MODULES`` with mypyc (``setup.py``) from the very
same Python files: one source, no second implementation to keep in step. The compiled code
does the same floating-point operations in the same order (C doubles; FMA contraction off),
so a recording replays bit for bit under either; ``tests/test_native.py`` replays every
golden both ways. Where no C compiler is found, or with ``VADE_REPLAY_PURE=1`` at install
time, nothing is compiled and the package is pure Python.

``VADE_REPLAY_PURE=1`` at run time imports the Python sources even where compiled modules
are installed: the reference the compiled build is checked against, and a way to rule the
build out when a replay differs between two machines.

This module is read by ``setup.py`` before the package is built: standard library only.
"""

from __future__ import annotations

import ast
import hashlib
import importlib.abc
import importlib.machinery
import importlib.util
import os
import sys

PACKAGE = "vade_replay"
# The modules a frame runs through (step, its dynamics, constraints, the encoder, the state
# and frame classes), as paths from the project root. I/O and the review stay Python.
MODULES = (
    "vade_replay/spatial.py",
    "vade_replay/constraints.py",
    "vade_replay/dynamics/free.py",
    "vade_replay/dynamics/onbase.py",
    "vade_replay/dynamics/velocity.py",
    "vade_replay/step.py",
    "vade_replay/codec.py",
    "vade_replay/state.py",
    "vade_replay/frames.py",
    "vade_replay/scene.py",
    "vade_replay/collision.py",
    "vade_replay/analysis.py",
)
# Written in C, with its Python reference beside it in the module that calls it: the frame
# messages written around orjson's numbers (``codec.FrameEncoder``, ``codec._frame_json_py``).
# Extension name -> source, from the project root. Built, and switched off, with the rest.
C_EXTENSIONS = {"vade_replay._framejson": "vade_replay/_framejson.c"}
PURE_ENV = "VADE_REPLAY_PURE"
# Set by CI: a build that cannot compile fails instead of installing pure Python, and the
# cross-build tests fail instead of skipping.
REQUIRE_ENV = "VADE_REPLAY_REQUIRE_COMPILED"
# Written by setup.py next to the modules when it compiles them: each source's SHA-256.
BUILT_FROM = "vade_replay/_compiled_from.py"
# How many C compilers the install runs at once (setup.py): every core unless set.
JOBS_ENV = "VADE_REPLAY_BUILD_JOBS"


def module_names() -> tuple[str, ...]:
    return tuple(path[:-3].replace("/", ".") for path in MODULES)


def pure_requested() -> bool:
    return os.environ.get(PURE_ENV, "") not in ("", "0")


def compiled_required() -> bool:
    return os.environ.get(REQUIRE_ENV, "") not in ("", "0")


def build_jobs(environ=None) -> tuple[int, str | None]:
    """The number of compilers the install runs at once: ``VADE_REPLAY_BUILD_JOBS`` (a
    whole number, at least 1), else every core. With a warning where the variable is set
    to anything else (the install goes on with every core)."""
    environ = os.environ if environ is None else environ
    cores = os.cpu_count() or 1
    text = environ.get(JOBS_ENV, "").strip()
    if not text:
        return cores, None
    if text.isdigit() and int(text) >= 1:
        return int(text), None
    return cores, (f"{JOBS_ENV}={text!r} is not a whole number of at least 1: compiling "
                   f"with {cores} jobs (every core)")


def source_hash(path: str) -> str:
    with open(path, "rb") as f:
        return hashlib.sha256(f.read()).hexdigest()


def built_from(root: str) -> dict[str, str] | None:
    """The source hashes recorded by the last compiling build under ``root``, or None."""
    try:
        with open(os.path.join(root, BUILT_FROM), encoding="utf-8") as f:
            value = ast.literal_eval(f.read().partition("=")[2].strip())
    except (OSError, ValueError, SyntaxError):
        return None
    return value if isinstance(value, dict) else None


def compiled() -> tuple[str, ...]:
    """The modules of ``MODULES`` that are loaded from compiled extensions (imports them)."""
    out = []
    for name in module_names():
        module = importlib.import_module(name)
        if (module.__file__ or "").endswith(tuple(importlib.machinery.EXTENSION_SUFFIXES)):
            out.append(name)
    return tuple(out)


def c_extensions() -> tuple[str, ...]:
    """The extensions of ``C_EXTENSIONS`` that are built and in use (``c_enabled``)."""
    if not c_enabled():
        return ()
    out = []
    for name in C_EXTENSIONS:
        try:
            importlib.import_module(name)
        except ImportError:
            continue
        out.append(name)
    return tuple(out)


def uncompiled_note() -> str | None:
    """What the commands say first where nothing is compiled though nobody asked for pure
    Python (``VADE_REPLAY_PURE``) and no source changed since a build (which warns of
    itself): the install found no C compiler (or mypy) and fell back quietly, and a
    newcomer's runs were 4x slower with nothing said but in ``pip install -v``."""
    if pure_requested() or _STALE or compiled():
        return None
    return ("note: vade_replay is not compiled here (its install found no C compiler, or no "
            "mypy): it runs as Python, 2.5-5x slower, with the same results. Install it again "
            "where a C compiler is found (README, \"The compiled build\"), or set "
            "VADE_REPLAY_PURE=1 to run it so without this note.")


# The compiled modules found stale on importing the package (``install_switch``).
_STALE: list[str] = []


def describe() -> str:
    """One line for summaries and benchmark tables: ``compiled 12/12 (mypyc), C 1/1`` or
    ``pure Python``."""
    names = compiled()
    if not names:
        # Why, where it is not a choice (a developer's trial: an edited module ran the
        # sources, and --json said "pure Python" and no more).
        why = f" ({PURE_ENV}=1)" if pure_requested() else \
            f" ({', '.join(_STALE)} changed since compiled)" if _STALE else ""
        return "pure Python" + why
    return f"compiled {len(names)}/{len(MODULES)} (mypyc), C {len(c_extensions())}/" \
        f"{len(C_EXTENSIONS)}"


def _extension(source: str) -> str | None:
    stem = os.path.splitext(source)[0]
    for suffix in importlib.machinery.EXTENSION_SUFFIXES:
        if os.path.isfile(stem + suffix):
            return stem + suffix
    return None


def stale(root: str) -> list[str]:
    """The compiled modules under ``root`` (the folder that holds the package) whose source
    is not the one they were compiled from: edited, or checked out, since the last build
    (by content: ``BUILT_FROM`` holds the hashes), or compiled by a build that left none."""
    hashes = built_from(root)
    out = []
    for path in (*MODULES, *C_EXTENSIONS.values()):
        source = os.path.join(root, path)
        if _extension(source) is None or not os.path.isfile(source):
            continue
        if hashes is None or hashes.get(path) != source_hash(source):
            out.append(path)
    return out


class _SourcesFirst(importlib.abc.MetaPathFinder):
    """Finds the Python source of a module in ``MODULES`` before its compiled extension."""

    def __init__(self) -> None:
        self.names = set(module_names())

    def find_spec(self, fullname, path, target=None):
        if fullname not in self.names or not path:
            return None
        leaf = fullname.rpartition(".")[2]
        for entry in path:
            source = os.path.join(entry, leaf + ".py")
            if os.path.isfile(source):
                return importlib.util.spec_from_file_location(fullname, source)
        return None


_C_OFF = False  # set by ``install_switch``: the C extensions' Python references run instead


def c_enabled() -> bool:
    """Whether the C extensions are to be used where built: not with ``VADE_REPLAY_PURE=1``,
    nor where any compiled module or C source changed since it was built."""
    return not _C_OFF


def install_switch(package_dir: str) -> None:
    """Called on importing the package. With ``VADE_REPLAY_PURE=1``, or when a compiled
    module was not built from its source as it is now (``stale``), every module of
    ``MODULES`` is imported from its source: compiled modules call each other directly, so
    one stale module among them would still run its old compiled code."""
    if any(isinstance(f, _SourcesFirst) for f in sys.meta_path):
        return
    global _C_OFF
    if pure_requested():
        _C_OFF = True
        sys.meta_path.insert(0, _SourcesFirst())
        return
    changed = stale(os.path.dirname(package_dir))
    if changed:
        _C_OFF = True
        _STALE[:] = changed
        import warnings
        # (Explicit, with no source line: a newcomer took the line warn prints under the
        # message for a traceback.)
        warnings.warn_explicit(
            f"vade_replay: {', '.join(changed)} changed since it was compiled; running the "
            "Python sources (slower, same results). Install the package again (`pip install "
            "-e .` in a checkout) to compile them.", RuntimeWarning, "vade_replay", 0)
        sys.meta_path.insert(0, _SourcesFirst())
