"""The notebook tutorial, executed from top to bottom by a real Jupyter kernel (nbclient): it runs
the sea experiment through the Python API, shows its recording inline with ``rerun-notebook``
(the same version as the SDK), a plugin beside the built-ins and a comparison."""

import importlib.metadata
from pathlib import Path

import nbformat
import rerun as rr
from nbclient import NotebookClient

NOTEBOOK = Path(__file__).resolve().parents[1] / "docs" / "tutorials" / "notebook.ipynb"
WIDGET = "application/vnd.jupyter.widget-view+json"


def test_rerun_notebook_matches_the_sdk():
    assert importlib.metadata.version("rerun-notebook") == rr.__version__


def test_the_notebook_runs(tmp_path):
    nb = nbformat.read(NOTEBOOK, as_version=4)
    assert not any(c.get("outputs") for c in nb.cells if c.cell_type == "code"), "commit it without outputs"
    NotebookClient(nb, timeout=900, kernel_name="python3", resources={"metadata": {"path": str(tmp_path)}}).execute()
    code = [c for c in nb.cells if c.cell_type == "code"]
    errors = [o for c in code for o in c.outputs if o.output_type == "error"]
    assert not errors, errors
    shown = [c for c in code if "workbench.show(" in c.source]
    assert len(shown) == 2 and all(any(WIDGET in o.get("data", {}) for o in c.outputs) for c in shown)
    text = "\n".join(o.get("text", "") + str(o.get("data", {}).get("text/markdown", ""))
                     for c in code for o in c.outputs)
    line = next(x for x in text.splitlines() if x.startswith("averaged: "))
    ours, raw = (float(w) for w in line.replace(" m", "").split() if w.replace(".", "").isdigit())
    assert ours < raw  # averaging the fixes beats the fixes
    assert "['lam=1', 'lam=0.99']" in text and "position RMSE" in text
