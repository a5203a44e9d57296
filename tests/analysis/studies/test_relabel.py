"""Labels against states on the toy run (`toy_run`): the identity relabelling reproduces the source's
round exactly; base-path labels keep the states and replace the actions at every decision."""

import json
import os

import numpy as np
import pytest

from soe_jax.analysis.studies import relabel
from soe_jax.data import hdf5
from soe_jax.experiment import loop, rundir
from soe_jax.experiment.rundir import RunDir

pytestmark = pytest.mark.usefixtures("toy_task")


def _round(workdir):
  config = rundir.load_config(workdir)
  loop.run(config, workdir, progress=False)
  return RunDir(workdir, config)


def test_the_identity_relabelling_reproduces_the_round_and_base_labels_change_only_actions(toy_run, tmp_path):
  root, config, workdir = toy_run
  source = RunDir(workdir, config)
  name = relabel.make(workdir, str(tmp_path / "identity"), "recorded")
  assert name == "soe-relabel_recorded"
  same = _round(str(tmp_path / "identity"))
  for phase in ("fit", "evaluate"):
    a, b = (json.load(open(r.phase_path(1, phase))) for r in (source, same))
    key = "loss_curve" if phase == "fit" else "success"
    assert a[key] == b[key]  # the same re-fit, the same outcomes, state by state
  relabel.make(workdir, str(tmp_path / "base"), "base")
  base = RunDir(str(tmp_path / "base"), rundir.load_config(str(tmp_path / "base")))
  kept, relabelled = (hdf5.read_episodes(r.data_path(1))[0] for r in (source, base))
  assert len(kept) == len(relabelled) > 0
  changed = False
  for a, b in zip(kept, relabelled):
    for k in a["obs"]:
      np.testing.assert_array_equal(a["obs"][k], b["obs"][k])  # the states stay
    changed |= not np.allclose(a["actions"], b["actions"])
  assert changed  # the labels do not
  assert os.path.exists(base.phase_path(1, "explore")) and not os.path.exists(base.phase_path(1, "fit"))


def test_the_relabel_command_exports_beside_a_campaigns_runs(toy_run, tmp_path):
  from soe_jax import __main__ as entry

  _, _, workdir = toy_run
  results = tmp_path / "results"
  entry.main(["soe_jax", "relabel", workdir, "--labels=recorded", f"--workdir={tmp_path / 'id'}",
              f"--results={results}", "--progress=false"])  # fmt: skip
  exported = results / "toy" / "seed0" / "soe-relabel_recorded"
  assert {"command.json", "config.json", "metrics.jsonl", "outcomes.json", "report.md"} <= set(os.listdir(exported))
  assert json.load(open(exported / "command.json"))["source_run"] == os.path.abspath(workdir)
  assert (results / "comparison.md").exists()
