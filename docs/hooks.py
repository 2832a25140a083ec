"""MkDocs hooks: publish the notebooks next to the pages, and show the docstrings' Sphinx roles as plain code."""

from __future__ import annotations

import re
from pathlib import Path

from mkdocs.structure.files import File

ROOT = Path(__file__).resolve().parents[1]
_ROLE = re.compile(r":(?:func|class|meth|mod|data|attr|exc|obj):<code>~?([^<]*)</code>")


def on_files(files, config):
    """Add ``notebooks/*.ipynb`` as static files, so the Notebooks page links to them."""
    for nb in sorted((ROOT / "notebooks").glob("*.ipynb")):
        files.append(File.generated(config, f"notebooks/{nb.name}", abs_src_path=str(nb)))
    return files


def on_page_content(html, page, config, files):
    """``:func:`~a.b``` in a docstring renders as ``<code>b</code>`` (``a.b`` without the tilde)."""
    return _ROLE.sub(lambda m: "<code>" + (m.group(1).rsplit(".", 1)[-1] if m.group(0).count("~") else m.group(1))
                     + "</code>", html)
