"""Shared by the ``_make_NN.py`` scripts: collect markdown and code cells, write them as a notebook.

    from _nbgen import Notebook

    nb = Notebook()
    md, code = nb.md, nb.code
    md(r'''# Title''')
    code(r'''print("hi")''')
    nb.write(HERE / "NN_name.ipynb")

The notebook is written without outputs, with the ``python3`` kernel spec and stable cell ids
(``cell-00``, ``cell-01``, ...), so regenerating an unchanged script gives the same file.
"""

from __future__ import annotations

from pathlib import Path

import nbformat
from nbformat.v4 import new_code_cell, new_markdown_cell, new_notebook

METADATA = {"kernelspec": {"display_name": "Python 3 (ipykernel)", "language": "python", "name": "python3"},
            "language_info": {"name": "python"}}


class Notebook:
    """The cells of one notebook, in order; :meth:`write` saves them."""

    def __init__(self) -> None:
        self.cells: list[tuple[str, str]] = []

    def md(self, text: str) -> None:
        """Append a markdown cell (leading and trailing newlines dropped)."""
        self.cells.append(("markdown", text.strip("\n")))

    def code(self, text: str) -> None:
        """Append a code cell (leading and trailing newlines dropped)."""
        self.cells.append(("code", text.strip("\n")))

    def write(self, path: str | Path) -> Path:
        """Validate and write the notebook to ``path``; print and return the path."""
        path = Path(path)
        nb = new_notebook(metadata=METADATA)
        nb.cells = [new_markdown_cell(src) if kind == "markdown" else new_code_cell(src) for kind, src in self.cells]
        for k, cell in enumerate(nb.cells):  # stable ids, so regenerating gives the same file
            cell.id = f"cell-{k:02d}"
        nbformat.validate(nb)
        nbformat.write(nb, path)
        print(f"wrote {path.relative_to(path.parent.parent) if path.is_absolute() else path}")
        return path
