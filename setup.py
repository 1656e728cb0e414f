"""The build: the package as pyproject.toml declares it, plus the per-frame modules compiled
by mypyc from the same Python sources (``vade_replay/native.py`` lists them and says why).

Nothing is compiled with ``VADE_REPLAY_PURE=1`` set at install time; a failed compile (no
C compiler) leaves those modules pure Python, with a warning from setuptools.
"""

import os
import runpy

from setuptools import setup

HERE = os.path.dirname(os.path.abspath(__file__))
NATIVE = runpy.run_path(os.path.join(HERE, "vade_replay", "native.py"))


def ext_modules():
    if NATIVE["pure_requested"]():
        return []
    try:
        from mypyc.build import mypycify
    except ImportError:  # built without the build requirements (--no-build-isolation)
        return []
    # Type errors in the modules imported by these are not theirs to fix here.
    extensions = mypycify(["--follow-imports=silent", *NATIVE["MODULES"]],
                          opt_level="3", separate=True)
    for extension in extensions:
        extension.optional = True  # no compiler: the pure-Python package still installs
        # Each a*b+c rounded twice, as CPython does it: no fused multiply-add (aarch64's
        # default), so the compiled modules give the same bits as their sources.
        extension.extra_compile_args = [*extension.extra_compile_args, "-ffp-contract=off"]
    return extensions


setup(ext_modules=ext_modules())
