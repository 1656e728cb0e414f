"""The build: the package as pyproject.toml declares it, plus the per-frame modules compiled
by mypyc from the same Python sources (``vade_replay/native.py`` lists them and says why).

Nothing is compiled with ``VADE_REPLAY_PURE=1`` set at install time; a failed compile (no
C compiler) leaves those modules pure Python, with a warning from setuptools.
"""

import glob
import os
import runpy
import shutil
import sys
import tempfile

from setuptools import setup

HERE = os.path.dirname(os.path.abspath(__file__))
NATIVE = runpy.run_path(os.path.join(HERE, "vade_replay", "native.py"))


def _remove_old_builds():
    """Compiled files of an earlier build, which would shadow the sources (in place)."""
    for path in NATIVE["MODULES"]:
        stem = os.path.join(HERE, path[:-3])
        for old in glob.glob(stem + ".*.so") + glob.glob(stem + "__mypyc.*.so") \
                + glob.glob(stem + ".*.pyd") + glob.glob(stem + "__mypyc.*.pyd"):
            os.remove(old)


def ext_modules():
    if {"egg_info", "dist_info"} & set(sys.argv[1:]):
        return []  # pip asking for requirements or metadata: mypyc's half-minute can wait
    if NATIVE["pure_requested"]():
        _remove_old_builds()
        return []
    try:
        from mypyc.build import mypycify
    except ImportError:  # built without the build requirements (--no-build-isolation)
        _remove_old_builds()
        return []
    # pip builds in an environment of the build requirements alone: numpy, trimesh and the
    # rest are missing there, so they are typed Any (as they are to the compiled code at run
    # time anyway). Type errors in the modules imported by these are not theirs to fix here.
    # A fresh mypy cache each build: an old one has made mypyc fail inside.
    cache = tempfile.mkdtemp(prefix="vade-mypy-cache-")
    try:
        extensions = mypycify(["--follow-imports=silent", "--ignore-missing-imports",
                               f"--cache-dir={cache}", *NATIVE["MODULES"]],
                              opt_level="3", separate=True)
    except (Exception, SystemExit) as exc:  # mypy refused them: install pure Python
        print(f"vade_replay: not compiling the per-frame modules ({exc!r}); "
              "they run as Python", file=sys.stderr)
        _remove_old_builds()
        return []
    finally:
        shutil.rmtree(cache, ignore_errors=True)
    for extension in extensions:
        extension.optional = True  # no compiler: the pure-Python package still installs
        # Each a*b+c rounded twice, as CPython does it: no fused multiply-add (aarch64's
        # default), so the compiled modules give the same bits as their sources.
        extension.extra_compile_args = [*extension.extra_compile_args, "-ffp-contract=off"]
    return extensions


setup(ext_modules=ext_modules(),
      options={"build_ext": {"parallel": os.cpu_count() or 1}})
