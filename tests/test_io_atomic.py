"""Atomic output: nothing left on failure, normal permissions on success."""
import os
import stat

import pytest

from sinscli.io.atomic import atomic_path


def test_success_renames_with_umask_permissions(tmp_path):
    old = os.umask(0o022)
    try:
        with atomic_path(tmp_path / "out.txt") as tmp:
            tmp.write_text("x")
    finally:
        os.umask(old)
    assert (tmp_path / "out.txt").read_text() == "x"
    assert stat.S_IMODE((tmp_path / "out.txt").stat().st_mode) == 0o644
    assert os.listdir(tmp_path) == ["out.txt"]


def test_failure_leaves_nothing_and_keeps_an_old_file(tmp_path):
    (tmp_path / "out.txt").write_text("old")
    with pytest.raises(RuntimeError):
        with atomic_path(tmp_path / "out.txt") as tmp:
            tmp.write_text("half")
            raise RuntimeError("boom")
    assert (tmp_path / "out.txt").read_text() == "old"
    assert os.listdir(tmp_path) == ["out.txt"]
