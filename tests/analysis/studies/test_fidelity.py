"""The fidelity study on the toy run (`toy_run`): a decision per Ta steps of every kept episode, each
measured, and the round-0 fit's beta KL from its record."""

import json
import os

import numpy as np
import pytest

from soe_jax.analysis.studies import fidelity
from soe_jax.experiment.rundir import RunDir

pytestmark = pytest.mark.usefixtures("toy_task")


def test_fidelity_measures_every_recorded_decision(toy_run):
  _, config, workdir = toy_run
  record = fidelity.Fidelity(samples=4, alphas=(0.0, 2.0)).run([workdir])
  (out,) = record["runs"]
  assert {"command", "commit", "machine"} <= set(record)
  run = RunDir(workdir, config)
  kept = run.kept(json.load(open(run.phase_path(1, "explore"))))
  ta = config.policy.n_action_steps
  assert out["episodes"] == len(kept) > 0
  assert out["decisions"] == sum(-(-len(ep["actions"]) // ta) for ep in kept)
  per = out["per_decision"]
  assert set(per) == {"base_spread", "recorded", "explore_alpha0", "explore_alpha2", "recon_eef", "recon_object",
                      "recon_relative"}  # fmt: skip
  assert all(len(v) == out["decisions"] and np.all(np.isfinite(v)) and min(v) >= 0 for v in per.values())
  fit0 = json.load(open(os.path.join(run.round0, "fit.json")))
  assert out["beta_kl"] == pytest.approx(config.policy.bypass.beta * fit0["final_metrics"]["kl"])
  assert "| toy | soe | 0 |" in fidelity.Fidelity.table([("toy", record)])
