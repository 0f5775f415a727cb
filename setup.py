"""setuptools' build step with the kernels compiled into the built package (issue 21; all metadata is in
pyproject.toml).  See _build/precompile.py for what runs and _build/backend.py for the build environment."""
import os
import subprocess
import sys
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py


class BuildPyWithKernels(build_py):
    """``build_py``, then the package's commands run once from the build tree so that numba's cache files
    (``__pycache__/*.nbi``, ``*.nbc``) go into the wheel.  Skipped for editable installs and with
    ``SINS_NO_PRECOMPILE=1``; a failure leaves a working package that compiles on first use."""

    def run(self):
        super().run()
        if getattr(self, "editable_mode", False) or os.environ.get("SINS_NO_PRECOMPILE"):
            return
        script = Path(__file__).resolve().parent / "_build" / "precompile.py"
        r = subprocess.run([sys.executable, str(script), self.build_lib])
        if r.returncode != 0:
            print("sinscli: kernels not precompiled (they compile on first use)", file=sys.stderr)


setup(cmdclass={"build_py": BuildPyWithKernels})
