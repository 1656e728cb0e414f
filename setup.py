"""The build: the package as pyproject.toml declares it, plus the per-frame modules compiled
by mypyc from the same Python sources (``vade_replay/native.py`` lists them and says why).

Nothing is compiled with ``VADE_REPLAY_PURE=1`` set at install time. Where mypy is missing
or refuses the modules, or the C compiler fails, the package installs as pure Python with a
warning on stderr (``pip install -v`` shows it); with ``VADE_REPLAY_REQUIRE_COMPILED=1``
(CI) the install fails instead. A compiling build writes ``vade_replay/_compiled_from.py``,
the hash of each source it compiled: the package runs the sources of any module edited
since (``native.stale``).
"""

import glob
import os
import pprint
import runpy
import shutil
import sys
import tempfile

from setuptools import Extension, setup

HERE = os.path.dirname(os.path.abspath(__file__))
NATIVE = runpy.run_path(os.path.join(HERE, "vade_replay", "native.py"))
IN_PLACE = bool({"editable_wheel", "develop", "--inplace", "-i"} & set(sys.argv[1:]))


def _warn(text):
    print(f"vade_replay: {text}", file=sys.stderr)


def _pure(reason):
    """Install pure Python, or fail where a compiled build is required (CI)."""
    if NATIVE["compiled_required"]() and not NATIVE["pure_requested"]():
        raise SystemExit(f"vade_replay: {reason}, and {NATIVE['REQUIRE_ENV']}=1 requires "
                         "the compiled build")
    _warn(f"{reason}: the per-frame modules run as Python (slower, same results)")
    if IN_PLACE:  # an earlier in-place build would shadow the sources
        for path in (*NATIVE["MODULES"], *NATIVE["C_EXTENSIONS"].values()):
            stem = os.path.join(HERE, os.path.splitext(path)[0])
            for old in glob.glob(stem + ".*.so") + glob.glob(stem + "__mypyc.*.so") \
                    + glob.glob(stem + ".*.pyd") + glob.glob(stem + "__mypyc.*.pyd"):
                os.remove(old)
        built_from = os.path.join(HERE, NATIVE["BUILT_FROM"])
        if os.path.exists(built_from):
            os.remove(built_from)
    return []


def _record_sources():
    hashes = {path: NATIVE["source_hash"](os.path.join(HERE, path))
              for path in (*NATIVE["MODULES"], *NATIVE["C_EXTENSIONS"].values())}
    with open(os.path.join(HERE, NATIVE["BUILT_FROM"]), "w", encoding="utf-8") as f:
        f.write('"""Written by setup.py: the sources the compiled modules were built '
                'from (SHA-256)."""\n\nSOURCES = ' + pprint.pformat(hashes) + "\n")


def ext_modules():
    if {"egg_info", "dist_info", "sdist"} & set(sys.argv[1:]):
        return []  # pip asking for requirements or metadata: mypyc's half-minute can wait
    if NATIVE["pure_requested"]():
        return _pure(f"{NATIVE['PURE_ENV']}=1")
    try:
        from mypyc.build import mypycify
    except ImportError:  # built without the build requirements (--no-build-isolation)
        return _pure("mypy (mypyc) is not installed")
    # pip builds in an environment of the build requirements alone: numpy, trimesh and the
    # rest are missing there, so they are typed Any (as they are to the compiled code at run
    # time anyway). Type errors in the modules imported by these are not theirs to fix here.
    # A fresh mypy cache each build: an old one has made mypyc fail inside.
    cache = tempfile.mkdtemp(prefix="vade-mypy-cache-")
    try:
        extensions = mypycify(["--follow-imports=silent", "--ignore-missing-imports",
                               f"--cache-dir={cache}", *NATIVE["MODULES"]],
                              opt_level="3", separate=True)
    except (Exception, SystemExit) as exc:  # mypy refused them
        return _pure(f"mypyc did not compile the per-frame modules ({exc!r})")
    finally:
        shutil.rmtree(cache, ignore_errors=True)
    _record_sources()
    # The C extensions (their Python references run where they are not built).
    extensions += [Extension(name, [path]) for name, path in NATIVE["C_EXTENSIONS"].items()]
    for extension in extensions:
        # No compiler: the pure-Python package still installs (not where CI requires it).
        extension.optional = not NATIVE["compiled_required"]()
        # Each a*b+c rounded twice, as CPython does it: no fused multiply-add (aarch64's
        # default), so the compiled modules give the same bits as their sources.
        extension.extra_compile_args = [*extension.extra_compile_args, "-ffp-contract=off"]
    return extensions


def _jobs() -> int:
    """Compilers at once: ``VADE_REPLAY_BUILD_JOBS``, else every core (native.build_jobs)."""
    jobs, warning = NATIVE["build_jobs"]()
    if warning:
        _warn(warning)
    return jobs


setup(ext_modules=ext_modules(),
      options={"build_ext": {"parallel": _jobs()}})
