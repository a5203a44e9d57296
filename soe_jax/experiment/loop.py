"""The self-improvement experiment (DESIGN.md, "Data flow"): `run(config, workdir)`.

Round 0: demonstrations (the scripted demonstrator, or an HDF5 file), the round-0 fit with the bypass
on, and its evaluation. The base path of that policy is a plain Diffusion Policy, so round 0 is shared
by every method run from the same settings (`rundir`).

Rounds r = 1..R: explore from the round's start states (the same for every method; new each round)
with the configured strategy and the previous round's policy, select episodes, write them to disk,
re-fit on the demonstrations plus everything selected so far (continuing from the previous parameters,
or from scratch), and evaluate the base path on the fixed evaluation start states, with the same
sampling keys in every round (so every method and round of a training seed is paired state by
state). Evaluation and exploration run the same rollout code. `rounds.new_data` makes the two
reference arms: `none`, the control, re-fits on the previous round's data alone with the same budget
(no exploration); `expert`, an oracle, explores as its method does and then adds the scripted
demonstrator's episodes from the start states the method kept instead of the method's own.

Every phase leaves its result before the next starts; running again on an interrupted workdir skips
finished phases, and since every key is `fold_in(seed, round, phase)` the numbers are the same as an
uninterrupted run's.
"""

from __future__ import annotations

import contextlib
import os

import ml_collections

from soe_jax.data import hdf5
from soe_jax.data.episodes import EpisodeSet, build_buffer
from soe_jax.envs import observations
from soe_jax.experiment import rundir, runlog, validation
from soe_jax.experiment.phases import Experiment
from soe_jax.experiment.rundir import RunDir
from soe_jax.experts import collect
from soe_jax.runtime import atomic, faults, hosts, locking
from soe_jax.train import normalization


def demonstrations(config: ml_collections.ConfigDict, env, progress: bool) -> list[dict]:
  """`config.data.num_demos` successful demonstrations: from `data.hdf5_path`, or scripted."""
  n = int(config.data.num_demos)
  if config.data.hdf5_path:
    path, key = config.data.hdf5_path, config.data.filter_key
    found, _ = hdf5.read_episodes(path, env, key)  # in this task's quaternion convention
    if len(found) < n:
      held = f"{path}{f' (filter key {key!r})' if key else ''} holds {len(found)} episodes"
      raise ValueError(f"{held}; data.num_demos asks for {n}")
    return found[:n]
  return collect.demonstrations(env, n, int(config.data.demo_seed), progress, config.data.demo_style)


def round0(exp: Experiment) -> tuple:
  """Round 0 in its shared directory: demonstrations, fit, evaluation (each reused when present), by one
  run at a time: another run of the same round 0 waits, then reads what this one wrote."""
  with locking.held(os.path.join(exp.dir.round0, ".lock"), f"round 0 ({exp.dir.round0}) is being made by another "
                    "run: waiting for it"):  # fmt: skip
    return _round0(exp)


def _round0(exp: Experiment) -> tuple:
  run = exp.dir
  atomic.remove_stale(run.round0)
  if not os.path.exists(run.demos_path):
    os.makedirs(run.round0, exist_ok=True)
    demos = demonstrations(exp.config, exp.env, exp.progress)
    with faults.site("demonstrations"):
      hdf5.write_episodes(run.demos_path, demos, dict(env_name=exp.env.name, env_kwargs=exp.env.config.to_dict(),
                                                      source="demonstrations"))  # fmt: skip
  demos = run.demonstrations()
  c, env = exp.config, exp.env
  floors = observations.select_keys(env.obs_min_span, env.object_dim, env.num_robots, exp.policy.lowdim_keys)
  norm = normalization.fit_normalizer(exp.policy, exp.spec, demos, c.policy.action_range,
                                      float(c.policy.normalizer_margin), floors)  # fmt: skip
  state = exp.fit_phase(0, [EpisodeSet(demos, 0)], norm)
  exp.evaluate_phase(0, state)
  exp.videos(0)
  return demos, norm, state


@contextlib.contextmanager
def opened(config: ml_collections.ConfigDict, workdir: str, progress: bool = True):
  """The `Experiment` of a checked config in `workdir`, created or resumed; the first line printed
  says whether it starts, resumes or has finished. (`run`, and the benchmarks that run phases.)"""
  print(f"workdir {workdir}: {rundir.status(workdir, config)}", flush=True)
  run_dir = RunDir.create(workdir, config)
  wandb = (
    runlog.WandbLog(workdir, rundir.plain(config), config.log.wandb_project)
    if config.log.wandb and hosts.writer()
    else None
  )
  with runlog.RunLog(workdir, wandb) as log:
    exp = Experiment(config, run_dir, progress, log)
    try:
      yield exp
    finally:
      exp.timer.close()


def run_round0(config: ml_collections.ConfigDict, workdir: str, progress: bool = True) -> None:
  """Round 0 alone, as `run` makes it in `workdir` (a campaign's first job on a cluster): running the
  run afterwards resumes after it. A config with a problem is refused (`UserError`) before anything is
  written."""
  validation.check(config)
  with opened(config, workdir, progress) as exp:
    round0(exp)


def run(config: ml_collections.ConfigDict, workdir: str, progress: bool = True) -> None:
  """Run (or resume) the experiment in `workdir` (its report is `analysis.report.write(workdir)`). A config with a problem
  is refused (`UserError`) before anything is written; the first line printed says whether the run
  starts, resumes or has finished."""
  validation.check(config)
  with opened(config, workdir, progress) as exp:
    if rundir.finished(workdir, config):  # nothing left to run (no round headers, no time left) but
      for r in range(int(config.rounds.num_rounds) + 1):  # the videos a kill may have left undrawn
        exp.videos(r)
      return
    clock = runlog.RoundClock(int(config.rounds.num_rounds))
    clock.begin(0)
    demos, norm, state = round0(exp)
    fit0, evaluate0 = (atomic.read_json(exp.dir.phase_path(0, p)) for p in ("fit", "evaluate"))
    expected = runlog.round_estimate(config, fit0, evaluate0)
    selected = []  # the episodes of the rounds done, one set per round
    for r in range(1, int(config.rounds.num_rounds) + 1):
      clock.begin(r, expected)
      if config.rounds.new_data != "none":  # (the control adds nothing)
        buf = build_buffer(config, exp.policy, [EpisodeSet(demos, 0)] + selected, exp.env)
        selected.append(EpisodeSet(exp.explore_phase(r, state, buf)[1], r))
      sets = [EpisodeSet(demos, 0)] + selected + exp.dir.steered_sets(r, config.rounds.steered == "successful")
      state = exp.fit_phase(r, sets, norm, state if config.rounds.refit == "continue" else None)
      exp.evaluate_phase(r, state)
      exp.videos(r)
