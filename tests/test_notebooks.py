"""The notebooks execute top to bottom, without an error in any cell, on a smoke run."""

import os

import nbformat
import pytest
from nbclient import NotebookClient

NOTEBOOKS = os.path.join(os.path.dirname(__file__), "..", "notebooks")


@pytest.mark.parametrize("name", [pytest.param("latent_analysis.ipynb", marks=pytest.mark.slow), "rounds.ipynb"])
def test_notebook_runs_on_a_smoke_run(name, smoke_run, monkeypatch):
  root, _, workdir, _ = smoke_run
  monkeypatch.setenv("SOE_WORKDIR", workdir)
  monkeypatch.setenv("SOE_RUNS", str(root))
  nb = nbformat.read(os.path.join(NOTEBOOKS, name), as_version=4)
  assert all(not c.get("outputs") for c in nb.cells if c.cell_type == "code"), "commit notebooks without outputs"
  NotebookClient(nb, timeout=600, kernel_name="python3", resources={"metadata": {"path": os.getcwd()}}).execute()
  outputs = [o for c in nb.cells if c.cell_type == "code" for o in c.outputs]
  errors = [f"{o.ename}: {o.evalue}" for o in outputs if o.output_type == "error"]
  assert not errors, errors
  warned = [o.text for o in outputs if o.output_type == "stream" and o.name == "stderr" and "Warning" in o.text]
  assert not warned, warned  # (no "Mean of empty slice" for round 0's missing exploration, no other warning)
  assert any(o.output_type == "display_data" for o in outputs)  # the figures were drawn
