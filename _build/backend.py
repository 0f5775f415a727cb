"""The build backend of ``pip install .``: setuptools, plus the package's run-time dependencies in the
build environment of a wheel, so that ``setup.py``'s build step can run the package's commands once and
ship the compiled numba kernels in the wheel (``_build/precompile.py``, issue 21).

An editable install (``pip install -e``) builds no kernels and needs no more than setuptools; so does any
build with ``SINS_NO_PRECOMPILE=1`` (the kernels then compile on first use, as numba does by default).
"""
from __future__ import annotations

import os
import tomllib
from pathlib import Path

from setuptools import build_meta as _setuptools
from setuptools.build_meta import *  # noqa: F401,F403  (every other hook as setuptools has it)


def _run_time_dependencies() -> list[str]:
    if os.environ.get("SINS_NO_PRECOMPILE"):
        return []
    with open(Path(__file__).resolve().parent.parent / "pyproject.toml", "rb") as f:
        return list(tomllib.load(f)["project"]["dependencies"])


def get_requires_for_build_wheel(config_settings=None):
    return _setuptools.get_requires_for_build_wheel(config_settings) + _run_time_dependencies()
