"""The kernels' cache directory is keyed by every source of the control package (mrodrake.control.compiled)."""

from __future__ import annotations

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
