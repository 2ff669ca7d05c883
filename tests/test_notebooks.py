"""Notebooks: stored without outputs, and each one runs from top to bottom and draws figures.

Every ``notebooks/*.ipynb`` is its own test, so ``pytest -n 2`` runs them in parallel. Each runs
in a fresh ``python3`` kernel (the one in this virtual environment; ``make`` installs its spec)
with a temporary working directory, so a notebook must not rely on relative paths.
"""

from pathlib import Path

import nbformat
import pytest
from jupyter_client.kernelspec import KernelSpecManager, NoSuchKernel
from nbclient import NotebookClient

pytestmark = pytest.mark.slow   # end to end: left out of `make test-fast`

NOTEBOOK_DIR = Path(__file__).resolve().parent.parent / "notebooks"
NOTEBOOKS = sorted(NOTEBOOK_DIR.glob("*.ipynb"))
CELL_TIMEOUT_S = 300  # per cell; generous for a slow CI machine (each notebook targets well under a minute)
KERNEL = "python3"


def _read(path: Path) -> nbformat.NotebookNode:
    nb = nbformat.read(path, as_version=4)
    nbformat.validate(nb)
    return nb


def _image_outputs(nb) -> int:
    return sum("image/png" in out.get("data", {})
               for cell in nb.cells if cell.cell_type == "code"
               for out in cell.outputs if out.output_type in ("display_data", "execute_result"))


def test_there_are_notebooks():
    assert NOTEBOOKS, f"no notebooks in {NOTEBOOK_DIR}"


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_stored_without_outputs(path):
    nb = _read(path)
    dirty = [i for i, cell in enumerate(nb.cells)
             if cell.cell_type == "code" and (cell.outputs or cell.execution_count is not None)]
    assert not dirty, f"{path.name}: code cells {dirty} hold outputs or execution counts; clear them before committing"


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_runs_and_draws_figures(path, tmp_path):
    try:
        KernelSpecManager().get_kernel_spec(KERNEL)
    except NoSuchKernel:
        pytest.fail(f"no Jupyter kernel named {KERNEL!r}: run `make test` (it installs one into .venv) or "
                    f"`python -m ipykernel install --sys-prefix --name {KERNEL}`")
    nb = _read(path)
    # Raises CellExecutionError (with the cell's traceback) if any cell fails.
    NotebookClient(nb, timeout=CELL_TIMEOUT_S, kernel_name=KERNEL,
                   resources={"metadata": {"path": str(tmp_path)}}).execute()
    assert nb.cells[0].cell_type == "markdown", f"{path.name}: the first cell should say what the notebook shows"
    assert _image_outputs(nb) >= 1, f"{path.name}: ran, but displayed no image/png figure"
    last_code = [cell for cell in nb.cells if cell.cell_type == "code"][-1]
    assert any("image/png" in out.get("data", {}) for out in last_code.outputs), \
        f"{path.name}: the last code cell should end in a figure"
