"""The run's logic end to end on the toy task (`toy.py`, the `toy_run` fixture): phases recorded in
order, resume after an interruption to the same numbers, extending a run, re-fits, the reference arms,
a fit stopped midway, demonstrations from a file; and that none of it loads MuJoCo or brax."""

import ast
import contextlib
import io
import json
import os
import pathlib
import signal
import subprocess
import sys

import chex
import jax
import numpy as np
import pytest
import toy

from soe_jax.data import hdf5
from soe_jax.data.episodes import EpisodeSet, build_buffer, policy_episode
from soe_jax.envs import observations
from soe_jax.envs.registry import make_env
from soe_jax.experiment import loop, phases, rundir, runlog
from soe_jax.experiment.rundir import RunDir
from soe_jax.runtime.errors import UserError
from soe_jax.train import checkpoint
from soe_jax.train import fit as fit_lib
from soe_jax.train import round as round_lib
from soe_jax.train.partial import PartialFit

pytestmark = pytest.mark.usefixtures("toy_task")

HERE = pathlib.Path(__file__).resolve().parent
TIMING = ("time_compile_s", "time_fit_s", "time_explore_s", "time_evaluate_s", "time_total_s", "time_steps_s")


def _numbers(workdir):
  return [{k: v for k, v in m.items() if k not in TIMING} for m in runlog.read_metrics(workdir)]


def _evaluated(workdir, r):
  return json.load(open(os.path.join(workdir, "rounds", str(r), "evaluate.json")))["success"]


def test_phases_are_recorded_in_order(toy_run):
  """Each phase's record, in order, with what it counted; the run's files; round 0 stored beside it."""
  _, config, workdir = toy_run
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
  kept = explore["num_episodes"]
  assert kept > 0 and [m["num_episodes"] for m in lines if m["phase"] == "fit"][:2] == [4, 4 + kept]
  for name in ("config.json", "data/round_1.hdf5", "rounds/2/ckpt/config.json"):
    assert os.path.exists(os.path.join(workdir, name)), name
  # Round 0 is stored once, beside the run, for every method with the same settings.
  assert os.path.exists(os.path.join(RunDir(workdir, config).round0, "ckpt", "config.json"))


def test_resume_gives_the_same_numbers(toy_run, monkeypatch):
  """A run stopped in round 2's fit resumes after its last finished phase (reading round 1's kept
  episodes back) to the uninterrupted run's numbers."""
  root, config, workdir = toy_run
  other = str(root / "toy-soe-interrupted")
  real = round_lib.RoundFit.fit
  calls = []

  def fit_then_stop(self, buf, norm, r, *args):
    if r == 2:
      calls.append(r)
      raise KeyboardInterrupt
    return real(self, buf, norm, r, *args)

  monkeypatch.setattr(round_lib.RoundFit, "fit", fit_then_stop)
  with pytest.raises(KeyboardInterrupt):
    loop.run(config, other, progress=False)
  assert calls == [2] and not os.path.exists(os.path.join(other, "rounds", "2", "fit.json"))
  monkeypatch.setattr(round_lib.RoundFit, "fit", real)
  loop.run(config, other, progress=False)
  assert _numbers(other) == _numbers(workdir)
  np.testing.assert_array_equal(_evaluated(other, 2), _evaluated(workdir, 2))


def test_more_rounds_extend_a_finished_run(toy_run):
  """A finished one-round run given a second round runs only that, to a two-round run's numbers."""
  root, config, workdir = toy_run
  short = toy.get_config("smoke,soe")
  short.rounds.num_rounds = 1
  other = str(root / "toy-soe-extended")
  loop.run(short, other, progress=False)
  assert [m["round"] for m in runlog.read_metrics(other)] == [0, 0, 1, 1, 1]
  loop.run(config, other, progress=False)
  assert _numbers(other) == _numbers(workdir)


def test_refit_runs_at_its_own_learning_rate(toy_run):
  root, config, workdir = toy_run
  still = toy.get_config("smoke,soe")
  still.rounds.update(num_rounds=1, refit_lr=1e-30)  # reuses the fixture's round 0
  other = str(root / "toy-soe-still")
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


def test_refit_restarts_or_carries_the_ema(toy_run):
  _, config, workdir = toy_run
  run = RunDir(workdir, config)
  base = checkpoint.load(run.ckpt_dir(0)).state
  steps = {}
  for mode in ("restart", "carry"):
    c = toy.get_config("smoke,soe")
    c.rounds.refit_ema = mode
    exp = phases.Experiment(c, RunDir(str(workdir) + "-" + mode, c), progress=False)
    buf = build_buffer(c, exp.policy, [EpisodeSet(run.demonstrations(), 0)])
    state, _ = exp.fitter.fit(
      buf, base.normalizer, 1, PartialFit(f"{workdir}-{mode}/fit_partial"), base, progress=False
    )
    steps[mode] = (int(state.step), state.ema_params)
  assert (steps["restart"][0], steps["carry"][0]) == (20, 60)  # carried: the decay goes on from round 0's 40
  leaves = [jax.tree.leaves(steps[m][1]) for m in ("restart", "carry")]
  assert any(not np.array_equal(a, b) for a, b in zip(*leaves))


def test_rescored_checkpoint_gives_the_same_success(toy_run):
  _, config, workdir = toy_run
  state = checkpoint.load(os.path.join(workdir, "rounds", "1", "ckpt")).state
  rescored = phases.Experiment(config, RunDir(workdir, config), progress=False).evaluate(state, 1)
  saved = json.load(open(os.path.join(workdir, "rounds", "1", "evaluate.json")))
  assert rescored["success"] == saved["success"] and rescored["jerk"] == pytest.approx(saved["jerk"])


def test_the_control_refits_on_the_demonstrations(toy_run):
  """The control (`rounds.new_data=none`) explores nothing and re-fits on the previous data alone, with
  the methods' re-fit budget."""
  root, _, _ = toy_run
  config = toy.get_config("smoke,control")  # beside the fixture: its round 0
  assert (config.method, config.rounds.new_data) == ("control", "none")
  workdir = str(root / "toy-control")
  loop.run(config, workdir, progress=False)
  lines = runlog.read_metrics(workdir)
  assert [(m["round"], m["phase"]) for m in lines] == [(0, "fit"), (0, "evaluate"), (1, "fit"), (1, "evaluate"),
                                                       (2, "fit"), (2, "evaluate")]  # fmt: skip
  fits = [m for m in lines if m["phase"] == "fit"]
  assert [m["num_episodes"] for m in fits] == [config.data.num_demos] * 3  # demonstrations only
  assert [m["steps"] for m in fits[1:]] == [config.rounds.refit_steps] * 2
  assert not os.path.exists(os.path.join(workdir, "data"))  # nothing explored, nothing kept


def test_expert_data_replaces_the_kept_episodes(toy_run, tmp_path):
  """The oracle arm (`rounds.new_data=expert`) keeps the demonstrator's episodes from the start states
  its exploration kept, each starting at its state."""
  _, config, workdir = toy_run
  oracle = toy.get_config("smoke,dp,expert_data")
  assert (oracle.method, oracle.rounds.new_data) == ("dp-expert_data", "expert")
  oracle.explore.strategy.name = "expert"  # an exploration that keeps every start state
  oracle.rounds.update(num_rounds=1, round0_dir=str(tmp_path / "round0"))
  exp = phases.Experiment(oracle, RunDir.create(str(tmp_path / "run"), oracle), progress=False)
  state = checkpoint.load(RunDir(workdir, config).ckpt_dir(0)).state
  rec, kept, _ = exp.explore(state, 1, build_buffer(oracle, exp.policy, []))
  n = oracle.explore.num_start_states
  assert rec["explored_episodes"] == n and rec["num_episodes"] == len(kept) == n  # the demonstrator's, all kept
  assert rec["expert_success_rate"] == 1.0 and all(ep["success"] for ep in kept)
  for ep, key in zip(kept, phases.exploration_starts(oracle, 1)[:: oracle.explore.tries]):  # round 1's states
    start = observations.policy_obs(exp.env.reset(key).obs)
    np.testing.assert_allclose(policy_episode(ep, exp.policy.lowdim_keys)["policy_obs"][0], start, atol=1e-6)


@pytest.mark.parametrize("stop", ["periodic save", "SIGINT", "SIGTERM"])
def test_stopped_fit_resumes_to_the_same_parameters(toy_run, tmp_path, monkeypatch, stop):
  """Stopped after the first chunk (step 20 of 40): by an exception right after the periodic save, or
  by a signal, which saves the fit itself (checkpoints off) and then stops."""
  _, config, workdir = toy_run
  again = toy.get_config("smoke,soe")
  again.rounds.update(num_rounds=0, round0_dir=str(tmp_path / "round0"))
  real_save, real_chunk_fn = PartialFit.save, fit_lib._chunk_fn
  saved = []

  def save(self, state, done, history):
    real_save(self, state, done, history)
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

  monkeypatch.setattr(PartialFit, "save", save)
  if stop != "periodic save":
    again.fit.checkpoint_every = 0
    monkeypatch.setattr(fit_lib, "_chunk_fn", chunk_fn)
  handlers = [signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)]
  with pytest.raises(KeyboardInterrupt):
    loop.run(again, str(tmp_path / "run"), progress=False)
  assert [signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)] == handlers  # the fit's are gone
  run = RunDir(str(tmp_path / "run"), again)
  assert saved == [20] and PartialFit(run.partial_fit_dir(0)).latest() == 20
  assert rundir.status(run.path, again) == "resuming round 0 (round 0's fit from step 20)"
  monkeypatch.undo()
  loop.run(again, str(tmp_path / "run"), progress=False)
  assert not os.path.exists(run.partial_fit_dir(0))  # cleared once the fit finished
  resumed = checkpoint.load(run.ckpt_dir(0)).state
  whole = checkpoint.load(RunDir(workdir, config).ckpt_dir(0)).state
  chex.assert_trees_all_equal((resumed.params, resumed.ema_params), (whole.params, whole.ema_params))
  fits = [json.load(open(r.phase_path(0, "fit")))["loss_curve"] for r in (run, RunDir(workdir, config))]
  assert fits[0] == fits[1]


def test_filter_key_takes_the_episodes_of_its_mask(toy_run, tmp_path):
  _, config, workdir = toy_run
  demos, _ = hdf5.read_episodes(RunDir(workdir, config).demos_path)
  path = str(tmp_path / "masked.hdf5")
  hdf5.write_episodes(path, demos + demos[:1], {"env_name": "toy"}, masks={"core_2": [len(demos), 1]})
  chosen = toy.get_config("smoke")
  chosen.data.update(hdf5_path=path, filter_key="core_2", num_demos=2)
  found = loop.demonstrations(chosen, make_env("toy"), progress=False)
  np.testing.assert_array_equal(found[0]["actions"], demos[1]["actions"])  # the mask's, in file order
  np.testing.assert_array_equal(found[1]["actions"], demos[0]["actions"])
  chosen.data.filter_key = "core_20"
  with pytest.raises(UserError, match=r"no filter key 'core_20'; its filter keys: core_2"):
    loop.run(chosen, str(tmp_path / "run"), progress=False)
  assert not os.path.exists(tmp_path / "run")


# The toy-task tests and what they import: their own modules, the fixtures', and the suite's conftest
# (its module level; its function-level imports serve the real tasks' fixtures).
TOY_TESTS = ("test_loop.py", "test_rundir.py", "conftest.py", "toy.py", "toy_config.py")


def _import_lines(path: pathlib.Path, top_level_only: bool = False) -> list[str]:
  tree = ast.parse(path.read_text())
  nodes = tree.body if top_level_only else ast.walk(tree)
  return [
    ast.unparse(n)
    for n in nodes
    if isinstance(n, ast.Import | ast.ImportFrom) and getattr(n, "module", "") != "__future__"
  ]


_WITHOUT_MUJOCO = """
import sys
sys.path.insert(0, {here!r})
{imports}
from soe_jax.runtime import compile_cache
compile_cache.enable()
import toy
from soe_jax.experiment import loop
config = toy.get_config("smoke,soe")
config.rounds.num_rounds = 1
with toy.registered():
  loop.run(config, {workdir!r}, progress=False)
print(sorted({{m.split(".")[0] for m in sys.modules}} & {{"mujoco", "brax"}}))
"""


@pytest.mark.slow
def test_the_toy_tests_import_no_mujoco(tmp_path):
  """Every module the toy-task tests import, and a one-round toy run, leave MuJoCo and brax unloaded."""
  lines = [line for name in TOY_TESTS for line in _import_lines(HERE / name)]
  lines += _import_lines(HERE.parent / "conftest.py", top_level_only=True)
  script = _WITHOUT_MUJOCO.format(here=str(HERE), imports="\n".join(lines), workdir=str(tmp_path / "run"))
  proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=600,
                        cwd=HERE.parent.parent)  # fmt: skip
  assert proc.returncode == 0, proc.stderr[-3000:]
  assert proc.stdout.strip().splitlines()[-1] == "[]"
  assert len(runlog.read_metrics(str(tmp_path / "run"))) == 5  # the run did run: rounds 0 and 1


def test_a_round_0_run_reports_round_0_alone(toy_run):
  """`rounds.num_rounds=0`: round 0's success (a calibration's number) and no improvement (+0.0%), no jerk
  of nothing (nan), no exploration figure."""
  from soe_jax.analysis import report

  root, _, _ = toy_run
  config = toy.get_config("smoke,soe")
  config.rounds.num_rounds = 0
  workdir = str(root / "toy-round0-only")
  loop.run(config, workdir, progress=False)  # (the fixture's round 0, shared)
  summary = report.write(workdir)
  assert summary["rounds"] == [0] and "improvement_rel" not in summary and "sr_after" not in summary
  assert summary["sr_before"] == summary["success_per_round"][0]
  text = open(os.path.join(workdir, "report.md")).read()
  assert "+0.0" not in text and "nan" not in text and "exploration.png" not in text
  assert os.path.exists(os.path.join(workdir, "success.png"))
  assert not os.path.exists(os.path.join(workdir, "exploration.png"))


def test_a_one_round_run_says_how_long_its_round_will_take(toy_run, capsys):
  """Before any round after round 0 has run, the estimate is round 0's pace."""
  root, _, _ = toy_run
  config = toy.get_config("smoke,soe")
  config.rounds.num_rounds = 1
  capsys.readouterr()
  loop.run(config, str(root / "toy-one-round"), progress=False)
  line = next(line for line in capsys.readouterr().out.splitlines() if line.startswith("== round 1 of 1"))
  assert "left at round 0's pace)" in line, line


def test_a_fit_says_how_long_it_will_take(tmp_path, capsys):
  """Once its second chunk has run (the first compiles), at that chunk's pace."""
  config = toy.get_config("smoke,soe")
  config.rounds.num_rounds = 0
  config.fit.num_steps = 3 * config.fit.chunk_size
  loop.run(config, str(tmp_path / "run"), progress=False)
  lines = [line for line in capsys.readouterr().out.splitlines() if line.startswith("round 0 fit: ")]
  assert len(lines) == 2 and " ms per step, about " in lines[0] and lines[0].endswith(" left of 60 steps"), lines


def test_a_finished_run_run_again_says_so_and_nothing_else(toy_run, capsys, monkeypatch):
  """No round headers and no time left: the run has nothing left to do (its phases are not entered)."""
  _, config, workdir = toy_run
  monkeypatch.setattr(loop, "round0", lambda exp: pytest.fail("a finished run entered round 0"))
  capsys.readouterr()
  loop.run(config, workdir, progress=False)
  assert capsys.readouterr().out.splitlines() == [
    f"workdir {workdir}: already finished (2 rounds); rewriting its report"
  ]


def test_the_fits_estimate_is_a_line_of_its_own_beside_a_progress_bar(tmp_path):
  """With progress bars on and stdout and stderr in one file (`> log 2>&1`), the estimate does not run on
  from the bar's line."""
  config = toy.get_config("smoke,soe")
  config.rounds.num_rounds = 0
  config.fit.num_steps = 3 * config.fit.chunk_size
  both = io.StringIO()
  with contextlib.redirect_stdout(both), contextlib.redirect_stderr(both):
    loop.run(config, str(tmp_path / "run"), progress=True)
  lines = both.getvalue().split("\n")
  assert any(line.startswith("round 0 fit: ") and " ms per step, about " in line for line in lines), lines


def test_a_policy_of_relative_poses_runs_and_acts_in_absolute_poses(tmp_path):
  """`policy.action_frame=chunk_relative`: round 0 and a round run; the normaliser spans the relative
  displacements (the goal 0.26-0.40 m ahead of the point in the training windows, where the commanded
  world x is 0.25-0.30 m); the agent's chunks go back to world positions: they reach goals."""
  config = toy.get_config("smoke,soe")
  config.policy.update(action_frame="chunk_relative", action_range="demonstrations")
  config.rounds.num_rounds = 1
  loop.run(config, str(tmp_path / "rel"), progress=False)
  loaded = checkpoint.load(os.path.join(tmp_path, "rel", "rounds", "1", "ckpt"))
  assert loaded.policy.frame is not None and loaded.policy.frame.obs_position == (0,)
  norm = loaded.state.normalizer
  lo, hi = (np.asarray(norm.unnormalize_actions(np.full(10, v)))[0] for v in (-1.0, 1.0))
  assert 0.2 < lo < 0.26 and 0.38 < hi < 0.5  # x displacements from the point to the goal, widened
  fit0 = json.load(open(RunDir(str(tmp_path / "rel"), config).phase_path(0, "fit")))
  assert 0.0 <= fit0["actions_clipped"] < 0.05
  assert np.mean(_evaluated(str(tmp_path / "rel"), 1)) > 0.2


def test_the_sime_protocol_retrains_each_round_from_fresh_parameters(toy_run):
  """`protocol=sime`: one observation step, 20-step chunks executed whole, SIME's selection, and round 1
  fitted from freshly initialised parameters (round 1's own initialisation key) with round 0's
  recipe. At a learning rate of 1e-30 a fit leaves its starting parameters: round 1's are then its
  fresh initialisation, not round 0's."""
  root, _, _ = toy_run
  config = toy.get_config("smoke,soe,protocol=sime")
  assert config.method == "soe-protocol_sime"
  assert (config.policy.n_obs_steps, config.policy.horizon, config.policy.n_action_steps) == (1, 20, 20)
  assert (config.rounds.select, config.rounds.refit) == ("sime", "scratch")
  config.rounds.num_rounds = 1
  config.fit.lr = 1e-30
  workdir = str(root / "toy-protocol-sime")
  loop.run(config, workdir, progress=False)
  run = RunDir(workdir, config)
  fit1 = json.load(open(run.phase_path(1, "fit")))
  assert fit1["steps"] == config.fit.num_steps  # round 0's recipe, not refit_steps
  exp = phases.Experiment(config, run, progress=False)
  fresh = exp.policy.init(jax.random.fold_in(exp.key(1, round_lib.FIT), 0))
  round0, round1 = (checkpoint.load(run.ckpt_dir(r)).state.params for r in (0, 1))
  chex.assert_trees_all_close(round1, fresh, atol=1e-12)
  assert max(float(np.abs(a - b).max()) for a, b in zip(jax.tree.leaves(round0), jax.tree.leaves(round1))) > 1e-3
