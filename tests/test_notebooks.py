"""The notebooks run top to bottom (nbclient) with a shortened simulation horizon, show their figures as images,
embed replays the notebook server can serve, and are stored clean."""

from __future__ import annotations

import re
from pathlib import Path

import nbformat
import pytest
from nbclient import NotebookClient

NOTEBOOKS = Path(__file__).resolve().parents[1] / "notebooks"
ALL = sorted(p.name for p in NOTEBOOKS.glob("*.ipynb"))
IFRAME_SRC = re.compile(r"<iframe\b[^>]*\bsrc=\"([^\"]+)\"", re.IGNORECASE)


def _outputs(nb):
    return [(i, o) for i, c in enumerate(nb.cells) if c.cell_type == "code" for o in c.outputs]


@pytest.mark.parametrize("name", ALL)
def test_notebook_stored_with_cleared_outputs(name):
    nb = nbformat.read(NOTEBOOKS / name, as_version=4)
    for cell in nb.cells:
        if cell.cell_type == "code":
            assert cell.outputs == [] and cell.execution_count is None, f"{name}: outputs not cleared"


@pytest.mark.parametrize("name", ALL)
def test_notebook_executes(name, monkeypatch):
    monkeypatch.setenv("MRODRAKE_NB_TMAX", "30")
    nb = nbformat.read(NOTEBOOKS / name, as_version=4)
    # allow_errors: run every cell so that the assertion below reports all failing cells at once
    NotebookClient(nb, timeout=900, kernel_name="python3", allow_errors=True,
                   resources={"metadata": {"path": str(NOTEBOOKS)}}).execute()
    outputs = _outputs(nb)

    errors = [f"cell {i}: {o.get('ename')}: {o.get('evalue')}" for i, o in outputs if o.get("output_type") == "error"]
    assert not errors, f"{name}: " + "; ".join(errors)

    # every notebook plots something: a figure that is not rendered leaves only text/plain "<Figure ...>"
    images = [i for i, o in outputs if "image/png" in o.get("data", {})]
    assert images, f"{name}: no image/png output (figures not displayed)"

    # embedded replays are addressed relative to the notebook and exist inside the notebooks/ directory, i.e.
    # below the root of `jupyter notebook notebooks/`
    for i, o in outputs:
        for src in IFRAME_SRC.findall(o.get("data", {}).get("text/html", "")):
            target = (NOTEBOOKS / src).resolve()
            assert not Path(src).is_absolute() and target.is_relative_to(NOTEBOOKS), f"{name} cell {i}: {src}"
            assert target.is_file(), f"{name} cell {i}: {src} not written"
