"""A real task's run end to end: Lift's smoke run (the `smoke_run` fixture), what it leaves (metrics,
report, plots, data), and the analyses that read a run or run beside it (aggregate, converge, latent).
The run's logic itself is tested on the toy task (`test_loop.py`; `compare` in analysis/test_campaign.py)."""

import json
import os
import shutil

import jax
import numpy as np
import pytest

from soe_jax.analysis import aggregate
from soe_jax.experiment import runlog
from soe_jax.experiment.rundir import RunDir
from soe_jax.runtime import atomic


def test_a_run_leaves_metrics_report_plots_and_data(smoke_run):
  """Every phase's record, the report and its plots, the TensorBoard log, the kept data and policies."""
  root, config, workdir, summary = smoke_run
  lines = runlog.read_metrics(workdir)  # (the phases' order and counts: tests/experiment/test_loop.py)
  assert [(m["round"], m["phase"]) for m in lines][-1] == (2, "evaluate")
  for m in (lines[1], lines[2]):  # a real task's rollout phases: the share of observation features outside [-1, 1]
    assert 0.0 <= m["obs_out_of_range"] <= 1.0
  for name in (
    "report.md",
    "outcomes.json",
    "success.png",
    "exploration.png",
    "config.json",
    "data/round_1.hdf5",
    "rounds/2/ckpt/config.json",
  ):
    assert os.path.exists(os.path.join(workdir, name)), name
  assert any(f.startswith("events.out.tfevents") for f in os.listdir(os.path.join(workdir, "tb")))
  import matplotlib.image

  for plot in ("success.png", "exploration.png"):
    assert matplotlib.image.imread(os.path.join(workdir, plot)).shape[1] >= 1000  # pixels wide
  text = open(os.path.join(workdir, "report.md")).read()
  assert "| soe |" in text and f"(n={config.eval.num_start_states})" in text
  assert (
    f"Paired with round 0 (the same {config.eval.num_start_states} start states and sampling keys): round 2" in text
  )
  assert summary["rounds"] == [0, 1, 2] and len(summary["success_per_round"]) == 3
  # Round 0 is stored once, beside the run, for every method with the same settings.
  assert os.path.exists(os.path.join(RunDir(workdir, config).round0, "ckpt", "config.json"))


def test_aggregate_table_over_runs(smoke_run, tmp_path):
  """One row per task, method and settings; a repeat of a seed is left out."""
  root, _, workdir, _ = smoke_run
  md, csv_text = aggregate.aggregate([workdir])
  assert "| lift | soe |  | 1 |" in md
  header, row = csv_text.splitlines()[:2]
  assert header.startswith("task,method,variant,seeds,pass_at_k") and header.endswith(",round_wall_s")
  assert float(row.split(",")[-1]) > 0  # the smoke run's rounds took time
  # A run with other settings gets its own row, named by what differs; a repeat of a seed is left out.
  copies = []
  for name, alpha in (("alpha3", 3.0), ("alpha3-again", 3.0)):
    copy = tmp_path / name
    shutil.copytree(workdir, copy, ignore=shutil.ignore_patterns("rounds", "data", "tb"))
    saved = json.loads((copy / "config.json").read_text())
    saved["explore"]["strategy"]["kwargs"]["alpha"] = alpha
    (copy / "config.json").write_text(json.dumps(saved))
    copies.append(str(copy))
  md, _ = aggregate.aggregate([workdir] + copies)
  assert (
    "| lift | soe | explore.strategy.kwargs.alpha=2.0 | 1 |" in md
    and "| lift | soe | explore.strategy.kwargs.alpha=3.0 | 1 |" in md
  )


@pytest.mark.slow
def test_in_fit_evaluations_leave_the_fit_as_it_is(smoke_run, tmp_path):
  """In-fit evaluations are recorded. The `converge` study on the smoke run's settings: round 0 with evaluations every 20 steps has the
  fixture's parameters (fitted without them), then the continuation and the paired check."""
  from soe_jax.analysis.studies import converge
  from soe_jax.train import checkpoint

  _, config, workdir, _ = smoke_run
  study = converge.Converge(eval_every=20, eval_states=3, check_states=4, extra=0.5,
                            workdir=str(tmp_path / "converge"), progress=False)  # fmt: skip
  result = study.run([], config)
  curve = result["fit"]["eval_curve"]
  assert [p["step"] for p in curve] == [20, 40] and all(len(p["success"]) == 3 for p in curve)
  assert (
    0 < curve[0]["fit_s"] < curve[1]["fit_s"] <= result["fit"]["time_steps_s"]
    and curve[1]["wall_s"] > curve[1]["fit_s"]
  )
  assert [p["step"] for p in result["continued"]["eval_curve"]] == [20] and result["continued"]["steps"] == 20
  run = RunDir(str(tmp_path / "converge"), converge.settings(config, 20, 3))
  with_evals, without = (checkpoint.load(RunDir(w, c).ckpt_dir(0)).state for w, c in
                         ((run.path, run.config), (workdir, config)))  # fmt: skip
  for a, b in zip(jax.tree.leaves(with_evals.params), jax.tree.leaves(without.params)):
    np.testing.assert_array_equal(a, b)
  assert {"command", "commit", "machine", "config"} <= set(result)
  check = result["check"]
  assert check["before"]["num_rollouts"] == check["after"]["num_rollouts"] == 4
  assert check["gained"] + check["lost"] <= 4 and isinstance(check["converged"], bool)
  assert "paired states" in converge.curve_lines(result)[-1]
  assert json.loads(study.report(result).splitlines()[-1])["converged"] == check["converged"]


@pytest.mark.slow  # (15 s; the latent's parts are tested in explore/test_steering.py)
def test_latent_explores_as_the_run_did(smoke_run):
  """The `latent` study beside the smoke run shares its round 0; its exploration is round 1's, episode
  for episode, and the effective dimensions are the SNR's above 0 dB, highest first."""
  from soe_jax.analysis.studies import latent

  root, config, workdir, _ = smoke_run
  result = latent.Latent(windows=64, workdir=str(root / "latent"), progress=False).run([], config)
  snr = result["latent"]["snr_db"]
  assert len(snr) == config.policy.bypass.latent_dim
  assert result["latent"]["effective_dims"] == sorted((i for i in range(len(snr)) if snr[i] > 0), key=lambda i: -snr[i])
  signal, noise = np.array(result["latent"]["signal_db"]), np.array(result["latent"]["noise_db"])
  np.testing.assert_allclose(signal - noise, snr, atol=2e-3)  # the SNR's two parts, each rounded
  ran = atomic.read_json(RunDir(workdir, config).phase_path(1, "explore"))
  assert result["explore"]["success"] == ran["success"] and result["explore"]["jerk"] == pytest.approx(ran["jerk"])
  evaluated = atomic.read_json(RunDir(workdir, config).phase_path(0, "evaluate"))
  assert result["round0"]["success"] == evaluated["success"]
  assert result["round0_dir"] == os.path.basename(RunDir(workdir, config).round0)
  assert latent.summary_lines(result)[0].startswith("round 0: ")
  assert "effective dimensions (above 0 dB)" in latent.summary_lines(result)[2]
