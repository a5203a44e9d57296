"""The experiment end to end on the smoke preset (the `smoke_run` fixture): outputs, resume after an
interruption, the shared round 0, re-scoring a checkpoint, and a refused config."""

import json
import os
import shutil
import signal
import subprocess
import sys

import chex
import jax
import numpy as np
import pytest

from configs import can as can_config
from configs import lift as lift_config
from configs import square as square_config
from soe_jax import aggregate, loop, rundir, runlog
from soe_jax.errors import UserError
from soe_jax.rundir import RunDir

TIMING = ("time_compile_s", "time_fit_s", "time_explore_s", "time_evaluate_s", "time_total_s", "time_steps_s")


def _numbers(workdir):
  return [{k: v for k, v in m.items() if k not in TIMING} for m in runlog.read_metrics(workdir)]


def test_a_run_leaves_metrics_report_plots_and_data(smoke_run):
  root, config, workdir, summary = smoke_run
  lines = runlog.read_metrics(workdir)
  assert [(m["round"], m["phase"]) for m in lines] == [
    (0, "fit"),
    (0, "evaluate"),
    (1, "explore"),
    (1, "fit"),
    (1, "evaluate"),
    (2, "explore"),
    (2, "fit"),
    (2, "evaluate"),
  ]
  for m in lines:
    assert set(runlog.LINE_KEYS) <= set(m)
    assert m["time_total_s"] >= m["time_compile_s"] >= 0
  explore = lines[2]
  assert explore["num_rollouts"] == config.explore.num_start_states * config.explore.tries
  assert explore["k"] == config.explore.tries and 0 <= explore["pass_at_k"] <= 1
  assert config.explore.num_start_states <= explore["rollouts"] <= explore["num_rollouts"]
  assert lines[1]["num_rollouts"] == config.eval.num_start_states
  for m in (lines[1], explore):  # every rollout phase: the share of observation features outside [-1, 1]
    assert 0.0 <= m["obs_out_of_range"] <= 1.0
  for name in (
    "report.md",
    "outcomes.json",
    "success.png",
    "exploration.png",
    "seeds.json",
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


def test_an_interrupted_run_resumes_to_the_same_numbers(smoke_run, monkeypatch):
  root, config, workdir, _ = smoke_run
  other = str(root / "lift-soe-interrupted")
  real = loop.Experiment.fit
  calls = []

  def fit_then_stop(self, buf, norm, r, *args):
    if r == 2:
      calls.append(r)
      raise KeyboardInterrupt
    return real(self, buf, norm, r, *args)

  monkeypatch.setattr(loop.Experiment, "fit", fit_then_stop)
  with pytest.raises(KeyboardInterrupt):
    loop.run(config, other, progress=False)
  assert calls == [2] and not os.path.exists(os.path.join(other, "rounds", "2", "fit.json"))
  monkeypatch.setattr(loop.Experiment, "fit", real)
  loop.run(config, other, progress=False)
  assert _numbers(other) == _numbers(workdir)
  ev = json.load(open(os.path.join(other, "rounds", "2", "evaluate.json")))
  np.testing.assert_array_equal(
    ev["success"], json.load(open(os.path.join(workdir, "rounds", "2", "evaluate.json")))["success"]
  )


def test_a_continued_refit_runs_at_its_own_learning_rate(smoke_run):
  root, config, workdir, _ = smoke_run
  from soe_jax import checkpoint

  still = lift_config.get_config("smoke,soe")
  still.rounds.update(num_rounds=1, refit_lr=1e-30)  # reuses the fixture's round 0
  other = str(root / "lift-soe-still")
  loop.run(still, other, progress=False)
  params = [
    checkpoint.load(os.path.join(d, "ckpt")).state.params
    for d in (
      RunDir(workdir, config).round0,
      os.path.join(other, "rounds", "1"),
      os.path.join(workdir, "rounds", "1"),
    )
  ]
  chex.assert_trees_all_close(params[0], params[1], atol=1e-12)  # a peak of 1e-30 leaves the round-0 parameters
  moved = [float(np.abs(a - b).max()) for a, b in zip(jax.tree.leaves(params[0]), jax.tree.leaves(params[2]))]
  assert max(moved) > 1e-4  # at fit.lr the same re-fit moves them


def test_a_continued_refit_restarts_or_carries_the_ema(smoke_run):
  from soe_jax import checkpoint

  _, config, workdir, _ = smoke_run
  from soe_jax.data.episodes import EpisodeSet, build_buffer

  run = RunDir(workdir, config)
  base = checkpoint.load(run.ckpt_dir(0)).state
  steps = {}
  for mode in ("restart", "carry"):
    c = lift_config.get_config("smoke,soe")
    c.rounds.refit_ema = mode
    exp = loop.Experiment(c, RunDir(str(workdir) + "-" + mode, c), progress=False)
    buf = build_buffer(c, exp.policy, [EpisodeSet(run.demonstrations(), 0)])
    state, _ = exp.fit(buf, base.normalizer, 1, base)
    steps[mode] = (int(state.step), state.ema_params)
  assert (steps["restart"][0], steps["carry"][0]) == (20, 60)  # carried: the decay goes on from round 0's 40
  leaves = [jax.tree.leaves(steps[m][1]) for m in ("restart", "carry")]
  assert any(not np.array_equal(a, b) for a, b in zip(*leaves))


def test_a_different_config_is_refused_naming_the_fields(smoke_run):
  _, config, workdir, _ = smoke_run
  changed = lift_config.get_config("smoke,soe")
  changed.explore.strategy.kwargs.alpha = 3.0
  changed.fit.lr = 1e-3
  with pytest.raises(ValueError, match=r"explore\.strategy\.kwargs\.alpha: 2\.0 -> 3\.0[\s\S]*fit\.lr"):
    loop.run(changed, workdir, progress=False)


def test_aggregate_table_over_runs(smoke_run, tmp_path):
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


def test_a_saved_checkpoint_rescored_gives_the_same_success(smoke_run):
  _, config, workdir, _ = smoke_run
  from soe_jax import checkpoint

  state = checkpoint.load(os.path.join(workdir, "rounds", "1", "ckpt")).state
  rescored = loop.Experiment(config, RunDir(workdir, config), progress=False).evaluate(state, 1)
  saved = json.load(open(os.path.join(workdir, "rounds", "1", "evaluate.json")))
  assert rescored["success"] == saved["success"] and rescored["jerk"] == pytest.approx(saved["jerk"])


def test_method_presets_choose_the_strategy():
  for method in ("dp", "sime", "soe", "soe_steer"):
    config = lift_config.get_config(f"cpu,{method}")
    assert config.method == config.explore.strategy.name == method
  assert lift_config.get_config("cpu,soe_steer").explore.strategy.kwargs.every == 4
  assert lift_config.get_config("smoke,soe").explore.strategy.kwargs.to_dict() == {"alpha": 2.0, "hold": 1}
  with pytest.raises(ValueError, match="choose one method preset"):
    lift_config.get_config("soe,dp")
  with pytest.raises(
    ValueError,
    match="known presets: smoke, cpu, head, image, expert_data, select, length_cap, alpha, hold, beta, dp, sime,",
  ):
    lift_config.get_config("fast")
  with pytest.raises(ValueError, match="expert_data goes with an exploring method"):
    lift_config.get_config("control,expert_data")


def test_variant_presets_set_their_field_and_name_the_method():
  c = lift_config.get_config("cpu,soe,select=shortest_success,length_cap=1.5,hold=4,alpha=1")
  assert c.method == "soe-select_shortest_success-cap1.5-alpha1-hold4"
  assert (c.rounds.select, c.rounds.length_cap) == ("shortest_success", 1.5)
  assert c.explore.strategy.kwargs.to_dict() == {"alpha": 1.0, "hold": 4}
  assert lift_config.get_config("sime,select=sime,expert_data").method == "sime-expert_data-select_sime"
  ablated = lift_config.get_config("soe,beta=0")
  assert (ablated.method, ablated.policy.bypass.beta) == ("soe-beta0", 0.0)
  assert rundir.round0_key(ablated) != rundir.round0_key(lift_config.get_config("soe"))  # a round 0 of its own
  for presets, message in [
    ("control,select=sime", "goes with an exploring method"),
    ("soe,alpha", "needs a value: alpha=VALUE"),
    ("dp,hold=2", "strategy 'dp' has no setting 'hold'"),
    ("soe,hold=two", "hold=two: expected a int, e.g. hold=1"),
  ]:
    with pytest.raises(ValueError, match=message):
      lift_config.get_config(presets)


def test_the_cpu_preset_takes_the_tasks_own_demonstrations_and_steps():
  lift, can, square = (config.get_config("cpu") for config in (lift_config, can_config, square_config))
  assert (lift.data.num_demos, lift_config.get_config("").data.num_demos) == (3, 10)
  assert can.data.num_demos == square.data.num_demos == can_config.get_config("").data.num_demos == 20
  assert [c.fit.num_steps for c in (lift, can, square)] == [12_500, 20_000, 20_000]
  assert lift.policy.head.kwargs.down_dims == (32, 64, 128) and lift.fit.lr == 1e-3 and lift.rounds.refit_lr == 3e-4
  assert can_config.get_config("cpu,smoke").data.num_demos == 4  # smoke stays tiny
  image = lift_config.get_config("cpu,image")  # Lift's image policy: robomimic's 10, fitted for 6k steps
  assert (image.data.num_demos, image.fit.num_steps, can_config.get_config("cpu,image").fit.num_steps) == (
    10,
    6_000,
    4_000,
  )


def test_a_rejected_config_writes_nothing(tmp_path):
  broken = tmp_path / "broken.hdf5"
  broken.write_text("not hdf5")
  for field, value, message in [
    ("env.task", "nope", "unknown task 'nope'; known tasks: can, lift, square, transport"),
    ("policy.head.name", "transformer", "known heads: diffusion_unet, flow_unet, mlp"),
    ("explore.strategy.name", "noise", "known strategies: dp, expert, sime"),
    ("explore.strategy.name", "sime", "strategy 'sime' has no setting 'alpha'"),  # soe's settings
    ("rounds.select", "best", "known selections: all_successes, first_success"),
    ("rounds.refit", "warm", "known: continue, scratch"),
    ("rounds.refit_lr", -1e-4, r"rounds.refit_lr must be >= 0"),
    ("rounds.length_cap", -1.5, r"rounds.length_cap must be >= 0"),
    ("rounds.steered", "some", "known: successful, all"),
    ("rounds.refit_ema", "keep", "known: restart, carry"),
    ("policy.bypass.batch_fraction", 0.0, r"batch_fraction must be in \(0, 1\]"),
    ("data.num_demos", -2, "data.num_demos must be at least 1, got -2"),
    ("eval.num_start_states", -3, "eval.num_start_states must be at least 1"),
    ("explore.tries", -1, "explore.tries must be at least 1"),
    ("fit.num_steps", -5, "fit.num_steps must be at least 1"),
    ("rounds.num_rounds", -1, "rounds.num_rounds must be >= 0"),
    ("policy.n_action_steps", 20, r"n_action_steps \(20\) must be at most"),
    ("data.hdf5_path", str(broken), "is not a readable HDF5 file"),
    ("data.hdf5_path", str(tmp_path / "absent.hdf5"), "does not exist"),
  ]:
    config = lift_config.get_config("smoke")
    config.update_from_flattened_dict({field: value})
    with pytest.raises(UserError, match=message):
      loop.run(config, str(tmp_path / "run"), progress=False)
    assert not os.path.exists(tmp_path / "run")


def test_a_demonstration_file_of_another_task_is_refused(smoke_run, tmp_path):
  _, config, workdir, _ = smoke_run
  square = square_config.get_config("smoke")
  square.data.hdf5_path = RunDir(workdir, config).demos_path  # lift's: a 10-number object vector
  with pytest.raises(UserError, match=r"obs 'object' has shape \(\d+, 10\), the task 'square' needs \(T, 14\)"):
    loop.run(square, str(tmp_path / "run"), progress=False)
  assert not os.path.exists(tmp_path / "run")


def test_a_filter_key_takes_the_episodes_of_its_mask(smoke_run, tmp_path):
  from soe_jax.data import hdf5
  from soe_jax.envs import make_env

  _, config, workdir, _ = smoke_run
  demos, _ = hdf5.read_episodes(RunDir(workdir, config).demos_path)
  path = str(tmp_path / "masked.hdf5")
  hdf5.write_episodes(path, demos + demos[:1], {"env_name": "lift"}, masks={"core_2": [len(demos), 1]})
  chosen = lift_config.get_config("smoke")
  chosen.data.update(hdf5_path=path, filter_key="core_2", num_demos=2)
  found = loop.demonstrations(chosen, make_env("lift"), progress=False)
  np.testing.assert_array_equal(found[0]["actions"], demos[1]["actions"])  # the mask's, in file order
  np.testing.assert_array_equal(found[1]["actions"], demos[0]["actions"])
  chosen.data.filter_key = "core_20"
  with pytest.raises(UserError, match=r"no filter key 'core_20'; its filter keys: core_2"):
    loop.run(chosen, str(tmp_path / "run"), progress=False)
  assert not os.path.exists(tmp_path / "run")


def test_logging_settings_neither_block_a_resume_nor_rename_a_run_and_wandb_must_be_installed(
  smoke_run, tmp_path, monkeypatch
):
  import importlib.util

  _, config, workdir, _ = smoke_run
  logged = lift_config.get_config("smoke,soe")
  logged.log.wandb = True
  rundir.check_config(workdir, logged)  # no mismatch: logging is not part of the run
  assert rundir.default_workdir(logged, "configs/lift.py:smoke,soe") == os.path.join("runs", "lift-soe-seed0")
  find_spec = importlib.util.find_spec
  monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "wandb" else find_spec(name, *a))
  with pytest.raises(UserError, match=r"log.wandb needs wandb, which is not installed: pip install -e '.\[wandb\]'"):
    loop.run(logged, str(tmp_path / "run"), progress=False)
  assert not os.path.exists(tmp_path / "run")


def test_the_same_command_names_the_same_workdir_and_says_it_resumes(smoke_run, tmp_path):
  _, config, workdir, _ = smoke_run
  spec = "configs/lift.py:smoke,soe"
  assert rundir.default_workdir(config, spec) == os.path.join("runs", "lift-soe-seed0")
  other = lift_config.get_config("smoke,soe")
  other.fit.lr = 1e-3
  named = rundir.default_workdir(other, spec)
  assert named.startswith(os.path.join("runs", "lift-soe-seed0-")) and named == rundir.default_workdir(other, spec)
  other.seed = 3
  assert rundir.default_workdir(other, spec).startswith(os.path.join("runs", "lift-soe-seed3-"))
  assert rundir.status(str(tmp_path / "new"), config) == "starting"
  assert rundir.status(workdir, config).startswith("already finished (2 rounds)")
  partial = tmp_path / "partial"
  shutil.copytree(workdir, partial, ignore=shutil.ignore_patterns("rounds", "data", "tb"))
  lines = (partial / "metrics.jsonl").read_text().splitlines()[:3]
  (partial / "metrics.jsonl").write_text("\n".join(lines) + "\n")
  assert rundir.status(str(partial), config) == "resuming after round 1 explore"


def test_a_misspelled_override_suggests_the_field():
  from soe_jax import configfile

  argv = [
    "--config.fit.stepz=3",
    "--config.rounds.num_round=2",
    "--config.fit.lr=1e-3",
    "--config.policy.head.kwargs=x",
  ]
  assert configfile.unknown_overrides("configs/lift.py:smoke", argv) == [
    "fit.stepz (did you mean fit.num_steps?)",
    "rounds.num_round (did you mean rounds.num_rounds?)",
  ]


def test_the_command_line_reports_a_user_error_on_one_line_and_exits_2(tmp_path):
  workdir = tmp_path / "run"
  bad = ["--config=configs/lift.py:smoke", "--config.data.num_demos=-2", f"--workdir={workdir}"]
  proc = subprocess.run([sys.executable, "-m", "soe_jax.main", *bad], capture_output=True, text=True, timeout=300)
  assert proc.returncode == 2
  assert proc.stderr.strip() == "error: data.num_demos must be at least 1, got -2"
  assert not workdir.exists() and "Failed to import warp" not in proc.stdout


def test_a_finished_run_can_be_extended_by_more_rounds(tmp_path):
  saved = lift_config.get_config("smoke")
  rundir.check_config(str(tmp_path), saved)
  more = lift_config.get_config("smoke")
  more.rounds.num_rounds = saved.rounds.num_rounds + 1
  rundir.check_config(str(tmp_path), more)  # accepted, and saved
  assert rundir.load_config(str(tmp_path)).rounds.num_rounds == saved.rounds.num_rounds + 1
  with pytest.raises(ValueError, match="rounds.num_rounds"):
    rundir.check_config(str(tmp_path), saved)  # fewer rounds than saved: refused


def test_a_workdir_saved_before_the_fields_were_renamed_is_refused_naming_them(tmp_path):
  config = lift_config.get_config("smoke")
  saved = rundir.plain(config)
  saved["env"]["horizon"] = saved["env"].pop("episode_length")
  saved["explore"].update(method="soe", alpha=2.0, steer=dict(every=1))
  (tmp_path / "config.json").write_text(json.dumps(saved))
  message = (
    r"renamed:\n  env.horizon -> env.episode_length\n  explore.alpha -> [\s\S]*explore.steer -> [\s\S]*new --workdir"
  )
  with pytest.raises(ValueError, match=message):
    loop.run(config, str(tmp_path), progress=False)
  with pytest.raises(ValueError, match="explore.method -> method"):
    rundir.load_config(str(tmp_path))


def test_a_workdir_saved_before_fields_were_added_reads_them_as_their_old_behaviour(tmp_path):
  config = lift_config.get_config("smoke")
  saved = rundir.plain(config)
  assert {"rounds.steered", "rounds.refit_ema", "fit.eval_every", "policy.bypass.batch_fraction"} <= set(rundir.ADDED)
  for field in rundir.ADDED:  # a config saved before any of them existed
    *sections, name = field.split(".")
    d = saved
    for part in sections:
      d = d[part]
    del d[name]
  (tmp_path / "config.json").write_text(json.dumps(saved))
  rundir.check_config(str(tmp_path), config)  # accepted as it is
  assert rundir.load_config(str(tmp_path)).rounds.steered == "successful"
  del saved["explore"]["strategy"]["kwargs"]["hold"]  # soe's settings: likewise
  (tmp_path / "config.json").write_text(json.dumps(saved))
  assert rundir.load_config(str(tmp_path)).explore.strategy.kwargs.hold == 1
  config.rounds.steered = "all"  # a different value is still a different config
  with pytest.raises(ValueError, match="rounds.steered: 'successful' -> 'all'"):
    rundir.check_config(str(tmp_path), config)
  evaluated = lift_config.get_config("smoke")
  evaluated.fit.eval_every = 10  # in-fit evaluations leave round 0 as it is
  assert rundir.round0_key(evaluated) == rundir.round0_key(lift_config.get_config("smoke"))


def test_compare_explores_each_method_as_its_preset_from_the_shared_round0(smoke_run):
  from soe_jax import compare, configfile

  root, config, workdir, _ = smoke_run
  configs = {m: configfile.load("configs/lift.py:smoke", m, {"seed": config.seed}) for m in ("dp", "soe_steer")}
  assert configs["soe_steer"].explore.strategy.kwargs.num_proposals == 4  # the smoke preset's steering
  rows = compare.compare(configs, str(root / "compare"), num_start_states=2, tries=2, progress=False)
  assert [(r["method"], r["strategy"], r["episodes"]) for r in rows] == [("dp", "dp", 4), ("soe_steer", "soe_steer", 4)]
  saved = json.load(open(os.path.join(root, "compare", "compare.json")))
  base = json.load(open(os.path.join(RunDir(workdir, config).round0, "evaluate.json")))
  assert saved["base"]["success_rate"] == base["success_rate"]  # the fixture's round 0, not a new fit
  assert "| soe_steer |" in open(os.path.join(root, "compare", "compare.md")).read()


@pytest.mark.parametrize("stop", [pytest.param("periodic save", marks=pytest.mark.slow), "SIGINT", "SIGTERM"])
def test_a_fit_interrupted_midway_resumes_to_the_same_parameters(smoke_run, tmp_path, monkeypatch, stop):
  """Stopped after the first chunk (step 20 of 40): by an exception right after the periodic save, or
  by a signal, which saves the fit itself (checkpoints off) and then stops."""
  from soe_jax import checkpoint
  from soe_jax import fit as fit_lib

  _, config, workdir, _ = smoke_run
  again = lift_config.get_config("smoke,soe")
  again.rounds.update(num_rounds=0, round0_dir=str(tmp_path / "round0"))
  real_save, real_chunk_fn = RunDir.save_partial_fit, fit_lib._chunk_fn
  saved = []

  def save(self, r, state, done, history):
    real_save(self, r, state, done, history)
    saved.append(done)
    if stop == "periodic save":
      raise KeyboardInterrupt

  def chunk_fn(*args):
    chunk = real_chunk_fn(*args)

    def signalled(*a):
      out = chunk(*a)
      os.kill(os.getpid(), getattr(signal, stop))  # arrives while the chunk's results are pending
      return out

    return signalled

  monkeypatch.setattr(RunDir, "save_partial_fit", save)
  if stop != "periodic save":
    again.fit.checkpoint_every = 0
    monkeypatch.setattr(fit_lib, "_chunk_fn", chunk_fn)
  handlers = [signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)]
  with pytest.raises(KeyboardInterrupt):
    loop.run(again, str(tmp_path / "run"), progress=False)
  assert [signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)] == handlers  # the fit's are gone
  run = RunDir(str(tmp_path / "run"), again)
  assert saved == [20] and os.path.exists(os.path.join(run.partial_fit_dir(0), "progress.json"))
  assert rundir.status(run.path, again) == "resuming round 0 (round 0's fit from step 20)"
  monkeypatch.undo()
  loop.run(again, str(tmp_path / "run"), progress=False)
  assert not os.path.exists(run.partial_fit_dir(0))  # cleared once the fit finished
  resumed = checkpoint.load(run.ckpt_dir(0)).state
  whole = checkpoint.load(RunDir(workdir, config).ckpt_dir(0)).state
  chex.assert_trees_all_equal((resumed.params, resumed.ema_params), (whole.params, whole.ema_params))
  fits = [json.load(open(r.phase_path(0, "fit")))["loss_curve"] for r in (run, RunDir(workdir, config))]
  assert fits[0] == fits[1]


def test_the_next_fit_takes_only_successful_steered_episodes_unless_told(tmp_path):
  from soe_jax.data import hdf5

  config = lift_config.get_config("smoke,soe")
  run = RunDir(str(tmp_path), config)
  episode = lambda ok: dict(obs={"a": np.zeros((3, 2))}, actions=np.zeros((3, 10)), success=ok)
  hdf5.write_episodes(run.steered_path(0), [episode(True), episode(False), episode(True)], dict(steered=True))
  assert [len(s.episodes) for s in run.steered_sets(1)] == [2]
  assert [len(s.episodes) for s in run.steered_sets(1, only_successful=False)] == [3]
  assert run.steered_sets(0) == [] and all(s.steered and s.source == 0 for s in run.steered_sets(1))


@pytest.mark.slow
def test_in_fit_evaluations_are_recorded_and_leave_the_fit_as_it_is(smoke_run, tmp_path):
  """`bench converge` on the smoke run's settings: round 0 with evaluations every 20 steps has the
  fixture's parameters (fitted without them), then the continuation and the paired check."""
  from soe_jax import checkpoint
  from soe_jax.bench import converge

  _, config, workdir, _ = smoke_run
  result = converge.run(config, str(tmp_path / "converge"), eval_every=20, eval_states=3, check_states=4,
                        extra=0.5, progress=False)  # fmt: skip
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


def test_the_latent_benchmark_explores_as_the_run_did_and_names_the_dimensions_above_0_db(smoke_run):
  """`bench latent` beside the smoke run shares its round 0; its exploration is round 1's, episode for
  episode, and the effective dimensions are the SNR's above 0 dB, highest first."""
  from soe_jax.bench import latent

  root, config, workdir, _ = smoke_run
  result = latent.run(config, str(root / "latent"), windows=64, progress=False)
  snr = result["latent"]["snr_db"]
  assert len(snr) == config.policy.bypass.latent_dim
  assert result["latent"]["effective_dims"] == sorted((i for i in range(len(snr)) if snr[i] > 0), key=lambda i: -snr[i])
  signal, noise = np.array(result["latent"]["signal_db"]), np.array(result["latent"]["noise_db"])
  np.testing.assert_allclose(signal - noise, snr, atol=2e-3)  # the SNR's two parts, each rounded
  ran = rundir.read_json(RunDir(workdir, config).phase_path(1, "explore"))
  assert result["explore"]["success"] == ran["success"] and result["explore"]["jerk"] == pytest.approx(ran["jerk"])
  evaluated = rundir.read_json(RunDir(workdir, config).phase_path(0, "evaluate"))
  assert result["round0"]["success"] == evaluated["success"]
  assert result["round0_dir"] == os.path.basename(RunDir(workdir, config).round0)
  assert latent.summary_lines(result)[0].startswith("round 0: ")
  assert "effective dimensions (above 0 dB)" in latent.summary_lines(result)[2]
