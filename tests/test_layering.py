"""The package's layering: a module imports only from its own pipeline stage or an earlier one, and every
module imports on its own.

Stages, lowest first (README "Layout"):

0. ``errors``, ``geometry``, ``packing`` (and the ``mrodrake`` package itself): helpers with no mrodrake imports
   above them;
1. ``logic/``: LTL and Büchi automata (needs only ``errors``);
2. ``scenario``: the typed scenario; its validation parses the task (logic) and checks P_s (packing);
3. ``ts``; 4. ``planning/``; 5. ``control/``; 6. ``execution/``; 7. ``systems/``; 8. ``viz/``;
9. the tools on top: ``run``, ``campaign``, ``bench/``, ``cli``, ``__main__``.

Every ``import`` and ``from ... import`` counts, also those inside functions; relative imports are resolved.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "mrodrake"

STAGES: list[tuple[str, tuple[str, ...]]] = [
    ("errors/geometry/packing", ("mrodrake.errors", "mrodrake.geometry", "mrodrake.packing")),
    ("logic", ("mrodrake.logic",)),
    ("scenario", ("mrodrake.scenario",)),
    ("ts", ("mrodrake.ts",)),
    ("planning", ("mrodrake.planning",)),
    ("control", ("mrodrake.control",)),
    ("execution", ("mrodrake.execution",)),
    ("systems", ("mrodrake.systems",)),
    ("viz", ("mrodrake.viz",)),
    ("tools", ("mrodrake.run", "mrodrake.campaign", "mrodrake.bench", "mrodrake.cli", "mrodrake.__main__")),
]


def modules() -> dict[str, tuple[Path, bool]]:
    """Dotted module name -> (file, is a package ``__init__``) for every module under mrodrake/."""
    out = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = list(path.relative_to(ROOT).with_suffix("").parts)
        is_pkg = parts[-1] == "__init__"
        out[".".join(parts[:-1] if is_pkg else parts)] = (path, is_pkg)
    return out


def stage(module: str) -> int | None:
    """Stage index of a dotted module name (the package ``mrodrake`` itself is stage 0), or None."""
    if module == "mrodrake":
        return 0
    for index, (_, prefixes) in enumerate(STAGES):
        if any(module == p or module.startswith(p + ".") for p in prefixes):
            return index
    return None


def imports(module: str, path: Path, is_pkg: bool, known: set[str]) -> list[tuple[int, str]]:
    """(line, imported mrodrake module) of every import in the file, nested ones included."""
    package = module.split(".") if is_pkg else module.split(".")[:-1]
    found = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), filename=str(path))):
        if isinstance(node, ast.Import):
            found += [(node.lineno, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package[:len(package) - (node.level - 1)]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            for alias in node.names:  # ``from pkg import submodule`` imports the submodule
                sub = f"{target}.{alias.name}"
                found.append((node.lineno, sub if sub in known else target))
    return [(line, name) for line, name in dict.fromkeys(found) if name == "mrodrake" or name.startswith("mrodrake.")]


def test_every_module_has_a_stage():
    assert [m for m in modules() if stage(m) is None] == []


def test_no_upward_imports():
    mods = modules()
    known = set(mods)
    violations = []
    for module, (path, is_pkg) in mods.items():
        own = stage(module)
        for line, target in imports(module, path, is_pkg, known):
            other = stage(target)
            if other is not None and other > own:
                violations.append(f"{path.relative_to(ROOT)}:{line}: {module} ({STAGES[own][0]}) imports "
                                  f"{target} ({STAGES[other][0]}), a later stage")
    assert violations == [], "\n".join(violations)


_IMPORT_EACH = r"""
import importlib, sys, traceback
failed = []
for name in sys.argv[1:]:
    for loaded in [m for m in sys.modules if m == "mrodrake" or m.startswith("mrodrake.")]:
        del sys.modules[loaded]
    try:
        importlib.import_module(name)
    except BaseException:
        failed.append(name + ":\n" + traceback.format_exc(limit=3))
print("\n".join(failed))
sys.exit(1 if failed else 0)
"""


def test_every_module_imports_on_its_own():
    """Each module imports with no other mrodrake module loaded (one interpreter; the mrodrake modules are
    dropped from ``sys.modules`` before each import, third-party ones stay loaded to keep this fast)."""
    names = [m for m in modules() if m != "mrodrake.__main__"]  # __main__ runs the CLI
    res = subprocess.run([sys.executable, "-c", _IMPORT_EACH, *names], capture_output=True, text=True,
                         cwd=ROOT, timeout=600)
    assert res.returncode == 0, res.stdout + res.stderr


def test_python_m_mrodrake():
    res = subprocess.run([sys.executable, "-m", "mrodrake", "--version"], capture_output=True, text=True,
                         cwd=ROOT, timeout=120)
    assert res.returncode == 0 and res.stdout.startswith("mrodrake "), res.stdout + res.stderr
