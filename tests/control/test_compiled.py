"""The kernels' cache directory is keyed by every source of the control package (mrodrake.control.compiled)."""

from __future__ import annotations

import os
import time
from pathlib import Path

from mrodrake.control import adaptive, compiled, treecode


def test_editing_any_module_of_the_package_changes_the_key(tmp_path):
    for name in ("caller.py", "callee.py"):
        (tmp_path / name).write_text(f"# {name}\n")
    (tmp_path / "notes.txt").write_text("not a source\n")
    before = compiled.sources_key(tmp_path)
    (tmp_path / "notes.txt").write_text("edited\n")
    assert compiled.sources_key(tmp_path) == before
    (tmp_path / "callee.py").write_text("# callee.py, edited\n")
    assert compiled.sources_key(tmp_path) != before


def test_a_caller_and_its_callee_in_other_modules_share_the_keyed_directory():
    """The control law (adaptive) compiles the treecode into itself: both are cached under CACHE_DIR, whose name
    carries the key of the sources as they are now."""
    assert compiled.CACHE_DIR is not None
    assert Path(compiled.CACHE_DIR).name.endswith(compiled.sources_key())
    for kernel in (adaptive._law_point, treecode.tree_point):
        assert Path(kernel._cache._cache_path).is_relative_to(compiled.CACHE_DIR)


def test_directories_of_other_sources_are_removed_only_when_untouched_for_a_day(tmp_path, monkeypatch):
    monkeypatch.setattr(compiled.config, "CACHE_DIR", str(tmp_path))
    old, recent = tmp_path / "mrodrake-kernels-0000000000000000", tmp_path / "mrodrake-kernels-1111111111111111"
    other = tmp_path / "someone-elses-cache"
    for d in (old, recent, other):
        d.mkdir()
    two_days_ago = time.time() - 2 * 86400.0
    os.utime(old, (two_days_ago, two_days_ago))
    os.utime(other, (two_days_ago, two_days_ago))
    path = Path(compiled._cache_dir())
    assert path.parent == tmp_path and path.name == "mrodrake-kernels-" + compiled.sources_key()
    assert not old.exists() and recent.exists() and other.exists()
