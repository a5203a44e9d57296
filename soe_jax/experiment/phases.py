"""The phases of one run (`Experiment`): round r's fit, exploration and evaluation, each computed once
and saved in the run directory with its record before the next starts (`rundir.RunDir.once`), with
every key `fold_in(seed, round, stream)` so that a resumed run's numbers are an uninterrupted run's.
`loop.run` strings them into rounds."""

from __future__ import annotations

import time

import jax
import jax.numpy as jnp
import ml_collections
import numpy as np

from soe_jax import metrics
from soe_jax.data.episodes import EpisodeSet
from soe_jax.experiment import runlog, task, video
from soe_jax.experiment import select as select_lib
from soe_jax.experiment.rundir import RunDir
from soe_jax.experts import collect
from soe_jax.experts import registry as expert_registry
from soe_jax.explore import registry as strategy_registry
from soe_jax.explore import rollout
from soe_jax.policies.agent import Agent
from soe_jax.render.pool import RenderError
from soe_jax.train import checkpoint
from soe_jax.train import round as round_lib
from soe_jax.train.partial import PartialFit

# Per-round key streams (the fit's: `round_lib.FIT`, 1).
_EXPLORE, _EVALUATE, _FIT_EVALUATE = 2, 3, 4


def evaluation_starts(config: ml_collections.ConfigDict, n: int | None = None) -> jax.Array:
  """The reset keys of the evaluation's `n` (default `eval.num_start_states`) start states: the same in
  every round and for every method of a training seed (which states depends on the count)."""
  return jax.random.split(jax.random.key(int(config.eval.seed)), int(n or config.eval.num_start_states))


def exploration_starts(config: ml_collections.ConfigDict, r: int) -> jax.Array:
  """The reset keys of round r's exploration: `explore.num_start_states` start states, new each round,
  the same for every method, each repeated `explore.tries` times (a state's tries adjacent)."""
  seed = jax.random.fold_in(jax.random.key(int(config.seed) + 1), r)  # (the training seed's own stream)
  return jnp.repeat(jax.random.split(seed, int(config.explore.num_start_states)), int(config.explore.tries), axis=0)


class Experiment:
  """The pieces of one run that every phase uses. The task and the policy are shared by runs with the
  same settings in one process, so their compiled programs are too."""

  def __init__(self, config: ml_collections.ConfigDict, run_dir: RunDir, progress: bool = True, log=None):
    self.config, self.dir, self.progress, self.log = config, run_dir, progress, log
    self.env = task.env(config)
    self.policy = task.policy(config)
    self.spec = task.spec(config)
    self.timer = runlog.CompileTimer()
    self.fitter = round_lib.RoundFit(self.policy, config, self.spec)

  def key(self, r: int, stream: int):
    return round_lib.round_key(self.config.seed, r, stream)

  def agent(self, state) -> Agent:
    return Agent.from_state(self.policy, state)

  def rollout(self, state, strategy, reset_keys, key, desc: str, progress: bool | None = None) -> dict:
    """One code path for evaluation and exploration."""
    c = self.config.rollout
    return rollout.rollout(
      self.env,
      self.agent(state),
      strategy,
      reset_keys,
      key,
      slice_size=int(c.slice_size) or None,
      decisions_per_call=int(c.decisions_per_call),
      progress=self.progress if progress is None else progress,
      desc=desc,
    )

  def evaluate(self, state, r: int, num_states: int | None = None, key=None, progress: bool | None = None) -> dict:
    """The base path from `num_states` (default `eval.num_start_states`) start states split from the
    evaluation seed (which states depends on the count), sampling with `key` (default: the evaluation
    key, the same in every round, so that rounds and methods are paired state by state)."""
    return self._evaluate(state, r, num_states, key, progress)[0]

  def _evaluate(self, state, r: int, num_states=None, key=None, progress=None) -> tuple[dict, dict]:
    """(`evaluate`'s record, the rollout)."""
    keys = evaluation_starts(self.config, num_states)
    key = self.key(0, _EVALUATE) if key is None else key
    out = self.rollout(state, strategy_registry.make_strategy("dp"), keys, key, f"round {r} evaluate", progress)
    rec = dict(
      metrics.rollout_summary(out, 1, state.normalizer, self.spec.control_hz),
      success=out["success"].astype(int).tolist(),
    )
    return rec, out

  def shown(self, out: dict) -> list[dict]:
    """A rollout's first `log.videos` episodes, to be watched."""
    n = len(out["success"])
    return rollout.from_rollout(out, np.arange(n) < int(self.config.log.videos), self.env.num_robots)

  def explore(self, state, r: int, buf) -> tuple[dict, list[dict], list[dict]]:
    """Round r's exploration with the configured strategy, prepared on the data in `buf` -> (record,
    the episodes it adds to the data, its first episodes to be watched)."""
    c = self.config.explore
    strategy = strategy_registry.make_strategy(c.strategy.name, self.env, **c.strategy.kwargs)
    strategy, extra = strategy.prepare(self.agent(state), buf, jax.random.fold_in(self.key(r, _EXPLORE), 1))
    tries = int(c.tries)
    reset_keys = exploration_starts(self.config, r)
    out = self.rollout(state, strategy, reset_keys, self.key(r, _EXPLORE), f"round {r} explore ({c.strategy.name})")
    max_length = None
    if cap := float(self.config.rounds.length_cap):  # a multiple of the demonstrations' mean length
      max_length = cap * np.mean([len(d["actions"]) for d in self.dir.demonstrations()])
    shape = (-1, tries)
    keep = select_lib.select(
      out["success"].reshape(shape), out["length"].reshape(shape), self.config.rounds.select, max_length
    ).reshape(-1)
    rec = dict(
      metrics.rollout_summary(out, tries, state.normalizer, self.spec.control_hz),
      strategy=c.strategy.name,
      num_episodes=int(keep.sum()),
      kept_length_mean=float(out["length"][keep].mean()) if keep.any() else None,
      max_kept_length=max_length,
      success=out["success"].astype(int).tolist(),
      **extra,
    )
    if "steered" in out["aux"]:
      rec["steered_fraction"] = float(out["aux"]["steered"].mean())
    if self.config.rounds.new_data == "expert":
      return (*self.expert_episodes(reset_keys[keep], rec), self.shown(out))
    return rec, rollout.from_rollout(out, keep, self.env.num_robots), self.shown(out)

  def expert_episodes(self, reset_keys, rec: dict) -> tuple[dict, list[dict]]:
    """The oracle's data: the scripted demonstrator's episodes from `reset_keys` (the start states an
    exploration kept), run as the demonstrations are (one plan from the start state, not re-planned
    at every decision as the `expert` strategy is: that one loses Square's nut on the peg's top), its
    successful ones in place of the exploration's."""
    n = int(reset_keys.shape[0])
    rec = dict(rec, explored_episodes=rec["num_episodes"], num_episodes=0, expert_success_rate=None)
    if n == 0:
      return rec, []
    expert = expert_registry.make_expert(self.env.name, self.config.data.demo_style)
    batch = collect.run_demos(self.env, expert, reset_keys, progress=self.progress)
    ok = batch["success"].astype(bool)
    return dict(rec, num_episodes=int(ok.sum()), expert_success_rate=float(ok.mean())), collect.split_episodes(batch)

  def timed(self, fn):
    """(fn(), {time_total_s, time_compile_s})."""
    self.timer.take()
    t = time.perf_counter()
    result = fn()
    total = time.perf_counter() - t
    return result, dict(time_total_s=round(total, 2), time_compile_s=round(min(self.timer.take(), total), 2))

  def phase(self, r: int, name: str, work, save=None, load=None):
    """`RunDir.once` with `work() -> (record, value)` timed, and the record logged once."""

    def compute():
      (record, value), times = self.timed(work)
      return dict(record, **times), value

    record, value = self.dir.once(r, name, compute, save, load)
    if self.log is not None:
      self.log.once(record, self.config.method)
    return record, value

  def fit_phase(self, r: int, sets: list[EpisodeSet], norm, init_state=None, steps: int | None = None):
    """Round r's fit on `sets` (`round.RoundFit`), its policy saved with the record -> the fitted
    TrainState."""
    partial = PartialFit(self.dir.partial_fit_dir(r))
    c = self.config

    def evaluate(state):  # round 0's key in every round: the curves of a fit and of its continuation are paired
      return self.evaluate(state, r, int(c.fit.eval_states), self.key(0, _FIT_EVALUATE), progress=False)

    def work():
      buf, clipped = self.fitter.data(sets, norm, self.dir.set_path, self.env)
      state, info = self.fitter.fit(buf, norm, r, partial, init_state, steps, self.progress, evaluate)
      return dict(info, num_episodes=sum(len(s.episodes) for s in sets), actions_clipped=clipped), state

    save = lambda state: self.fitter.save(self.dir.ckpt_dir(r), state, partial)
    load = lambda _: checkpoint.load(self.dir.ckpt_dir(r), self.spec).state
    return self.phase(r, "fit", work, save, load)[1]

  def explore_phase(self, r: int, state, buf) -> tuple[dict, list[dict]]:
    """Round r's exploration (prepared on `buf`) -> its record and the episodes it kept, saved with it
    (and its first episodes, to be watched)."""
    meta = dict(
      env_name=self.env.name, strategy=self.config.explore.strategy.name, new_data=self.config.rounds.new_data
    )

    def work():
      rec, kept, shown = self.explore(state, r, buf)
      return rec, (kept, shown)

    def save(value):
      self.dir.save_kept(r, value[0], meta)
      self.dir.save_shown(r, "explore", value[1], meta)

    record, (kept, _) = self.phase(r, "explore", work, save, lambda rec: (self.dir.kept(rec), None))
    return record, kept

  def evaluate_phase(self, r: int, state) -> dict:
    """Round r's evaluation -> its record, saved with its first episodes (to be watched)."""

    def work():
      rec, out = self._evaluate(state, r)
      return rec, self.shown(out)

    save = lambda shown: self.dir.save_shown(r, "evaluate", shown, dict(env_name=self.env.name))
    return self.phase(r, "evaluate", work, save)[0]

  def videos(self, r: int) -> None:
    """Draw round r's stored episodes to MP4 (`video`), once; a renderer that cannot start is a warning,
    not the run's end (the run can draw them later: `python -m soe_jax video`)."""
    if not int(self.config.log.videos):
      return
    try:
      video.render_round(self.dir, self.env, r, redraw=False)
    except (RenderError, OSError) as e:
      print(f"warning: round {r}'s videos were not drawn: {e}", flush=True)
