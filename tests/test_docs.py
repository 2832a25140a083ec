"""The docs site: the README's test command builds it (and .ci/run runs that command), and every public
function or class the README names is in the API reference (``::: module`` directives under docs/api/)."""

from __future__ import annotations

import ast
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text(encoding="utf-8")
#: The entry points users call from notebooks; the API reference must document them whatever the README says.
ENTRY_POINTS = ["load_scenario", "TransitionSystem", "plan_scenario", "Mission", "run_mission", "run_campaign"]


def _test_command() -> str:
    lines = [ln.strip() for ln in README.splitlines() if ln.strip().startswith('pip install -e ".[test')]
    assert len(lines) == 1, lines
    return lines[0]


def test_ci_runs_the_readme_command_which_builds_the_docs():
    command = _test_command()
    assert "mkdocs build --strict" in command
    ci = [ln.strip() for ln in (ROOT / ".ci" / "run").read_text(encoding="utf-8").splitlines()]
    assert command in ci


def test_site_is_ignored():
    assert "site/" in (ROOT / ".gitignore").read_text(encoding="utf-8").split()
    assert re.search(r"^site_dir: site$", (ROOT / "mkdocs.yml").read_text(encoding="utf-8"), re.M)


def _module_file(module: str) -> Path | None:
    base = ROOT.joinpath(*module.split("."))
    for path in (base.with_suffix(".py"), base / "__init__.py"):
        if path.is_file():
            return path
    return None


def _public_names(path: Path) -> set[str]:
    """Top-level functions and classes of a module, and the names its ``__all__`` re-exports."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    names = {n.name for n in tree.body if isinstance(n, (ast.FunctionDef, ast.ClassDef)) and not n.name.startswith("_")}
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(isinstance(t, ast.Name) and t.id == "__all__" for t in node.targets):
            names |= {e.value for e in node.value.elts if isinstance(e, ast.Constant)}
    return names


def _documented() -> dict[str, set[str]]:
    out = {}
    for page in sorted((ROOT / "docs" / "api").glob("*.md")):
        for module in re.findall(r"^::: ([\w.]+)", page.read_text(encoding="utf-8"), re.M):
            path = _module_file(module)
            assert path is not None, f"{page.name}: no module {module}"
            out[module] = _public_names(path)
    return out


def _package_names() -> set[str]:
    names = set()
    for path in (ROOT / "mrodrake").rglob("*.py"):
        names |= _public_names(path)
    return names


def test_every_function_the_readme_names_is_in_the_api_reference():
    documented = _documented()
    known = _package_names()
    named = set(ENTRY_POINTS)
    for ref in re.findall(r"`((?:mrodrake\.)?[A-Za-z_][\w.]*)\(", README):
        *module, name = ref.split(".")
        if module and module[0] != "mrodrake":
            continue  # another library's function (os.abort)
        if module or name in known:
            named.add(ref)
    missing = []
    for ref in sorted(named):
        *module, name = ref.split(".")
        if module:
            ok = name in documented.get(".".join(module), set())
        else:
            ok = any(name in names for names in documented.values())
        if not ok:
            missing.append(ref)
    assert not missing, f"not in the API reference (docs/api/*.md): {missing}"
