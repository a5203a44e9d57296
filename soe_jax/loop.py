"""The self-improvement experiment (DESIGN.md, "Data flow"): `run(config, workdir)`.

Round 0: demonstrations (the scripted demonstrator, or an HDF5 file), the round-0 fit with the bypass
on, and its evaluation. The base path of that policy is a plain Diffusion Policy, so round 0 is shared
by every method run from the same config and seed: it is stored once under `round0_dir` (by default
`<workdir>/../round0/<task>-<hash of the fields it depends on>`) and reused.

Rounds r = 1..R: explore from the round's start states (the same for every method; new each round)
with the configured strategy and the previous round's policy, select episodes, write them to
`data/round_<r>.hdf5` (atomically), re-fit on the demonstrations plus everything selected so far
(continuing from the previous parameters, or from scratch), and evaluate the base path on the fixed
evaluation start states. Evaluation and exploration run the same rollout code.

Every phase leaves its result (`rounds/<r>/<phase>.json`, checkpoints under `rounds/<r>/ckpt`) before
the next starts; running again on an interrupted workdir skips finished phases, and since every key is
`fold_in(seed, round, phase)` the numbers are the same as an uninterrupted run's. A config that differs
from the workdir's saved one is refused, naming the fields.
"""

from __future__ import annotations

import functools
import hashlib
import json
import os
import time

import jax
import jax.numpy as jnp
import ml_collections
import numpy as np

from soe_jax import buffer as buffer_lib
from soe_jax import checkpoint, metrics, report, rollout, runlog, train_state
from soe_jax import fit as fit_lib
from soe_jax.data import hdf5
from soe_jax.envs import manipulation, registry
from soe_jax.experts import collect
from soe_jax.experts import registry as expert_registry
from soe_jax.explore import select as select_lib
from soe_jax.explore import steering, strategies
from soe_jax.policies import normalizer as normalizer_lib

CONFIG_FILE = "config.json"
SEEDS_FILE = "seeds.json"
# Per-round key streams.
_FIT, _EXPLORE, _EVALUATE = 1, 2, 3
# Sections that do not change round 0 (so methods differing only there share it).
_NOT_ROUND0 = ("explore", "rounds")


# -- config bookkeeping --------------------------------------------------------------------------


def config_diff(saved: dict, current: dict) -> list[str]:
  """Fields whose values differ, as 'a.b: saved -> current'."""
  a, b = runlog.flatten(saved), runlog.flatten(current)
  return [
    f"{k}: {a.get(k, '<missing>')!r} -> {b.get(k, '<missing>')!r}"
    for k in sorted(set(a) | set(b))
    if a.get(k, "<missing>") != b.get(k, "<missing>")
  ]


def _plain(config: ml_collections.ConfigDict) -> dict:
  return json.loads(config.to_json())


def _write_json(path: str, obj) -> None:
  tmp = f"{path}.tmp-{os.getpid()}"
  with open(tmp, "w") as f:
    json.dump(obj, f, indent=2)
  os.replace(tmp, path)


def _read_json(path: str):
  with open(path) as f:
    return json.load(f)


def check_config(workdir: str, config: ml_collections.ConfigDict) -> None:
  """Save the config in a new workdir; refuse one that differs from a workdir's saved config, except
  for more `rounds.num_rounds` (extending a finished run, e.g. after steering its last round)."""
  path = os.path.join(workdir, CONFIG_FILE)
  current = _plain(config)
  if os.path.exists(path):
    saved = _read_json(path)
    extended = current["rounds"]["num_rounds"] > saved["rounds"]["num_rounds"]
    if extended:
      saved["rounds"]["num_rounds"] = current["rounds"]["num_rounds"]
    diff = config_diff(saved, current)
    if diff:
      raise ValueError(
        f"the config does not match the one saved in {path}; differing fields:\n  "
        + "\n  ".join(diff)
        + "\nuse a new --workdir, or the saved config"
      )
    if extended:
      _write_json(path, current)
  else:
    _write_json(path, current)


def round0_key(config: ml_collections.ConfigDict) -> str:
  fields = {k: v for k, v in _plain(config).items() if k not in _NOT_ROUND0}
  digest = hashlib.sha1(json.dumps(fields, sort_keys=True).encode()).hexdigest()[:10]
  return f"{config.env.task}-{digest}"


def round0_dir(config: ml_collections.ConfigDict, workdir: str) -> str:
  base = config.rounds.round0_dir or os.path.join(os.path.dirname(os.path.abspath(workdir)), "round0")
  return os.path.join(base, round0_key(config))


def load_config(workdir: str) -> ml_collections.ConfigDict:
  """The config saved in a run's workdir."""
  path = os.path.join(workdir, CONFIG_FILE)
  if not os.path.exists(path):
    raise FileNotFoundError(f"{workdir!r} is not a run directory: {CONFIG_FILE} is missing")
  return ml_collections.ConfigDict(_read_json(path))


def checkpoint_dir(config: ml_collections.ConfigDict, workdir: str, r: int) -> str:
  """Where round `r`'s policy is saved (round 0: the shared round-0 directory)."""
  path = (
    os.path.join(round0_dir(config, workdir), "ckpt") if r == 0 else os.path.join(workdir, "rounds", str(r), "ckpt")
  )
  if not os.path.exists(os.path.join(path, checkpoint.CONFIG_FILE)):
    raise FileNotFoundError(f"round {r} of {workdir!r} has no checkpoint at {path} (not run yet?)")
  return path


def last_round(config: ml_collections.ConfigDict, workdir: str) -> int:
  """The last round with a saved checkpoint (0 if only round 0 has one)."""
  rounds_dir = os.path.join(workdir, "rounds")
  done = (
    [
      int(d)
      for d in os.listdir(rounds_dir)
      if d.isdigit() and os.path.exists(os.path.join(rounds_dir, d, "ckpt", checkpoint.CONFIG_FILE))
    ]
    if os.path.isdir(rounds_dir)
    else []
  )
  return max(done, default=0)


# -- data ---------------------------------------------------------------------------------------
def split_policy_obs(obs: np.ndarray) -> dict:
  """(T, D) policy observations -> robomimic's keys (`manipulation.POLICY_OBS_KEYS`)."""
  sizes = {"robot0_eef_pos": 3, "robot0_eef_quat": 4, "robot0_gripper_qpos": 2}
  out, start = {}, 0
  for k in manipulation.POLICY_OBS_KEYS:
    size = sizes.get(k, obs.shape[-1] - start)
    out[k] = obs[..., start : start + size]
    start += size
  return out


def policy_episode(ep: dict) -> dict:
  """An HDF5 episode -> {"policy_obs" (T, D), "actions" (T, A)} for the buffer."""
  obs = np.concatenate([np.asarray(ep["obs"][k], np.float32) for k in manipulation.POLICY_OBS_KEYS], -1)
  return {"policy_obs": obs, "actions": np.asarray(ep["actions"], np.float32)}


def rollout_episodes(out: dict, mask: np.ndarray) -> list[dict]:
  """The episodes of a rollout output where `mask` (N,) is set, trimmed to their lengths."""
  eps = []
  for i in np.flatnonzero(mask):
    t = int(out["length"][i])
    eps.append(
      dict(
        obs=split_policy_obs(out["obs"][i, :t]),
        actions=out["actions"][i, :t],
        states=out["qpos"][i, :t],
        success=bool(out["success"][i]),
      )
    )
  return eps


def demonstrations(config: ml_collections.ConfigDict, env, progress: bool) -> list[dict]:
  """`config.data.num_demos` successful demonstrations: from `data.hdf5_path`, or scripted."""
  n = int(config.data.num_demos)
  if config.data.hdf5_path:
    episodes, _ = hdf5.read_episodes(config.data.hdf5_path)
    if len(episodes) < n:
      raise ValueError(f"{config.data.hdf5_path} holds {len(episodes)} episodes; data.num_demos asks for {n}")
    return episodes[:n]
  keys = jax.random.split(jax.random.PRNGKey(config.data.demo_seed), 2 * n)  # spare start states
  batch = collect.run_demos(env, expert_registry.make_expert(env.name), keys, progress=progress)
  episodes = collect.split_episodes(batch, only_successful=True)
  if len(episodes) < n:
    raise RuntimeError(f"the {env.name} demonstrator succeeded {len(episodes)} times in {2 * n} tries; need {n}")
  return episodes[:n]


def build_buffer(config, policy, episode_sets: list[tuple]) -> buffer_lib.EpisodeBuffer:
  """A buffer of fixed capacity from (episodes, source[, steered]) tuples (source 0 = demonstrations,
  r = round r; steered: episodes a person steered on the steering page)."""
  buf = buffer_lib.create(int(config.data.capacity), int(config.data.max_length), policy.obs_dim, policy.action_dim)
  total = sum(len(e[0]) for e in episode_sets)
  if total > buf.capacity:
    raise ValueError(f"{total} episodes do not fit in data.capacity={buf.capacity}; raise it")
  for episodes, source, *steered in episode_sets:
    if episodes:
      n = len(episodes)
      p = buffer_lib.pad_episodes([policy_episode(e) for e in episodes], buf.max_length)
      buf = buffer_lib.add(
        buf, p["obs"], p["actions"], p["length"], np.ones(n, bool), source, np.full(n, bool(steered and steered[0]))
      )
  return buf


def steered_episodes(workdir: str, before_round: int) -> list[tuple]:
  """Episodes saved from the steering page with the policies of rounds < `before_round`."""
  out = []
  for q in range(before_round):
    path = os.path.join(workdir, "data", f"steered_round_{q}.hdf5")
    if os.path.exists(path):
      out.append((hdf5.read_episodes(path)[0], q, True))
  return out


# -- phases -------------------------------------------------------------------------------------
def start_keys(config: ml_collections.ConfigDict) -> dict:
  """The evaluation start states (fixed) and each round's exploration seed, saved with the run."""
  return dict(eval_seed=int(config.eval.seed), explore_seed=int(config.seed) + 1)


def _rollout_metrics(out: dict, tries: int) -> dict:
  s = out["success"].reshape(-1, tries)
  sr = metrics.success_rate(out["success"])
  rec = dict(
    success_rate=sr["rate"],
    num_rollouts=sr["num_episodes"],
    wilson_low=sr["wilson_low"],
    wilson_high=sr["wilson_high"],
    jerk=metrics.average_jerk(out["eef_pos"], out["length"] + 1),
    mean_length=float(out["length"].mean()),
  )
  if tries > 1:
    r = metrics.rollouts(s)
    rec.update(k=tries, pass_at_k=metrics.pass_at_k(s), rollouts=r["sum"], rollouts_mean=r["mean"])
  return rec


@functools.lru_cache(maxsize=8)
def task_env(env_json: str):
  """The task `config.env.to_json()` describes, built once per process."""
  return registry.env_from_config(ml_collections.ConfigDict(json.loads(env_json)))


@functools.lru_cache(maxsize=8)
def _policy(config_json: str):
  return checkpoint.policy_from_config(ml_collections.ConfigDict(json.loads(config_json)))


class Experiment:
  """The pieces of one run that every phase uses. The task and the policy are shared by runs with the
  same settings in one process, so their compiled programs are too."""

  def __init__(self, config: ml_collections.ConfigDict, workdir: str, progress: bool = True):
    self.config, self.workdir, self.progress = config, os.path.abspath(workdir), progress
    self.env = task_env(config.env.to_json())
    self.policy = _policy(json.dumps({k: _plain(config)[k] for k in ("env", "policy")}))
    self.root = jax.random.PRNGKey(int(config.seed))
    self.timer = runlog.CompileTimer()
    self._optimizers = {}

  def optimizer(self, steps: int, lr: float):
    """One optimiser object per schedule, so later rounds reuse the compiled fit chunks."""
    if (steps, lr) not in self._optimizers:
      self._optimizers[steps, lr] = train_state.make_optimizer(self.config.fit, steps, lr)
    return self._optimizers[steps, lr]

  def key(self, r: int, stream: int):
    return jax.random.fold_in(jax.random.fold_in(self.root, r), stream)

  # rollouts: one code path for evaluation and exploration
  def _rollout(self, state, strategy, reset_keys, key, desc):
    slice_size = int(self.config.explore.slice_size) or None
    return rollout.rollout(
      self.env,
      self.policy,
      strategies.Agent.from_state(state),
      strategy,
      reset_keys,
      key,
      slice_size=slice_size,
      decisions_per_call=int(self.config.explore.decisions_per_call),
      progress=self.progress,
      desc=desc,
    )

  def evaluate(self, state, r: int) -> dict:
    n = int(self.config.eval.num_start_states)
    keys = jax.random.split(jax.random.PRNGKey(int(self.config.eval.seed)), n)
    out = self._rollout(state, strategies.make_strategy("none"), keys, self.key(r, _EVALUATE), f"round {r} evaluate")
    return dict(_rollout_metrics(out, 1), success=out["success"].astype(int).tolist())

  def explore(self, state, r: int, buf) -> tuple[dict, list[dict]]:
    c = self.config.explore
    dims = ()
    extra = {}
    if c.strategy == "soe_steer":
      snr = steering.buffer_snr(
        self.policy,
        strategies.Agent.from_state(state),
        buf,
        jax.random.fold_in(self.key(r, _EXPLORE), 1),
        int(c.steer.snr_windows),
      )
      dims = steering.steering_dims(snr, float(c.steer.threshold_db), int(c.steer.max_dims) or None)
      extra = dict(snr_db=[round(float(x), 2) for x in snr], steer_dims=list(dims))
    strategy = strategies.make_strategy(c.strategy, c, env=self.env, dims=dims)
    seeds = start_keys(self.config)
    states = jax.random.split(jax.random.fold_in(jax.random.PRNGKey(seeds["explore_seed"]), r), int(c.num_start_states))
    tries = int(c.tries)
    reset_keys = jnp.repeat(states, tries, axis=0)  # the k tries of a start state are adjacent
    out = self._rollout(state, strategy, reset_keys, self.key(r, _EXPLORE), f"round {r} explore ({c.strategy})")
    keep = select_lib.select(out["success"].reshape(-1, tries), self.config.rounds.select).reshape(-1)
    rec = dict(
      _rollout_metrics(out, tries),
      strategy=c.strategy,
      num_episodes=int(keep.sum()),
      success=out["success"].astype(int).tolist(),
      **extra,
    )
    if "steered" in out["aux"]:
      rec["steered_fraction"] = float(out["aux"]["steered"].mean())
    return rec, rollout_episodes(out, keep)

  def fit(self, buf, norm, r: int, init_state=None):
    """Round 0 / scratch: fresh parameters, `fit.num_steps` at `fit.lr`; continue: from `init_state`,
    `rounds.refit_steps` at `rounds.refit_lr` (0: `fit.lr`)."""
    c = self.config
    if init_state is None:
      steps, lr = int(c.fit.num_steps), float(c.fit.lr)
      params = self.policy.init(jax.random.fold_in(self.key(r, _FIT), 0))
    else:
      steps, lr = int(c.rounds.refit_steps), float(c.rounds.refit_lr or c.fit.lr)
      params = init_state.params
    tx = self.optimizer(steps, lr)
    # fit donates its input state: build it from copies, so `norm` and `init_state` stay usable.
    state = jax.tree.map(jnp.copy, train_state.create(params, tx, norm, ema=c.fit.ema))
    state, history = fit_lib.fit(
      self.policy,
      tx,
      state,
      buf,
      jax.random.fold_in(self.key(r, _FIT), 1),
      steps,
      c.fit,
      progress=self.progress,
      desc=f"round {r} fit",
    )
    return state, dict(steps=steps, final_loss=history[-1]["loss"], loss_curve=[h["loss"] for h in history])

  def timed(self, fn):
    """(fn(), {time_total_s, time_compile_s})."""
    self.timer.take()
    t = time.perf_counter()
    result = fn()
    total = time.perf_counter() - t
    return result, dict(time_total_s=round(total, 2), time_compile_s=round(min(self.timer.take(), total), 2))


def demonstrations_path(config: ml_collections.ConfigDict, workdir: str) -> str:
  """The run's demonstrations, in its shared round-0 directory."""
  return os.path.join(round0_dir(config, workdir), "demos.hdf5")


def round0(exp: Experiment) -> tuple:
  """Round 0 in its shared directory: demonstrations, fit, evaluation (each reused when present)."""
  directory = round0_dir(exp.config, exp.workdir)
  os.makedirs(directory, exist_ok=True)
  demos_path = demonstrations_path(exp.config, exp.workdir)
  if not os.path.exists(demos_path):
    episodes = demonstrations(exp.config, exp.env, exp.progress)
    hdf5.write_episodes(demos_path, episodes, dict(env_name=exp.env.name, source="demonstrations"))
  demos, _ = hdf5.read_episodes(demos_path)
  flat = [policy_episode(e) for e in demos]
  norm = normalizer_lib.fit(
    np.concatenate([e["policy_obs"] for e in flat]),
    np.concatenate([e["actions"] for e in flat]),
    margin=float(exp.config.policy.normalizer_margin),
  )
  ckpt = os.path.join(directory, "ckpt")
  fit_path = os.path.join(directory, "fit.json")
  if os.path.exists(fit_path):
    state = checkpoint.load(ckpt).state
  else:
    buf = build_buffer(exp.config, exp.policy, [(demos, 0)])
    (state, info), times = exp.timed(lambda: exp.fit(buf, norm, 0))
    checkpoint.save(ckpt, state, exp.config)
    _write_json(fit_path, dict(info, round=0, phase="fit", num_episodes=len(demos), **times))
  eval_path = os.path.join(directory, "evaluate.json")
  if not os.path.exists(eval_path):
    rec, times = exp.timed(lambda: exp.evaluate(state, 0))
    _write_json(eval_path, dict(rec, round=0, phase="evaluate", **times))
  return demos, norm, state


LINE_KEYS = (
  "round",
  "phase",
  "method",
  "success_rate",
  "num_rollouts",
  "wilson_low",
  "wilson_high",
  "pass_at_k",
  "k",
  "rollouts",
  "rollouts_mean",
  "jerk",
  "num_episodes",
  "time_compile_s",
  "time_fit_s",
  "time_explore_s",
  "time_evaluate_s",
  "time_total_s",
)


def _line(rec: dict, method: str) -> dict:
  """The metrics.jsonl line of a phase record: the common keys first (None where a phase has no such
  number), then the phase's own; per-episode lists stay in the phase's JSON file."""
  line = {k: rec.get(k) for k in LINE_KEYS}
  line.update(method=method, **{k: 0.0 for k in ("time_fit_s", "time_explore_s", "time_evaluate_s")})
  line[f"time_{rec['phase']}_s"] = round(rec["time_total_s"] - rec["time_compile_s"], 2)
  line.update({k: v for k, v in rec.items() if k not in line and k not in ("success", "loss_curve")})
  return line


REFITS = ("continue", "scratch")


def validate(config: ml_collections.ConfigDict) -> None:
  """What would otherwise only fail after round 0's fit: strategy, selection, re-fit mode and rate."""
  strategies.check_name(config.explore.strategy)
  select_lib.check_name(config.rounds.select)
  if config.rounds.refit not in REFITS:
    raise ValueError(f"unknown re-fit mode {config.rounds.refit!r}; known: {', '.join(REFITS)}")
  if config.rounds.refit_lr < 0:
    raise ValueError(f"rounds.refit_lr must be >= 0 (0: fit.lr), got {config.rounds.refit_lr}")


def run(config: ml_collections.ConfigDict, workdir: str, progress: bool = True) -> dict:
  """Run (or resume) the experiment in `workdir`; returns the report's numbers."""
  validate(config)
  os.makedirs(workdir, exist_ok=True)
  check_config(workdir, config)
  seeds_path = os.path.join(workdir, SEEDS_FILE)
  if not os.path.exists(seeds_path):
    _write_json(seeds_path, start_keys(config))
  exp = Experiment(config, workdir, progress)
  log = runlog.RunLog(workdir)
  logged = {(m["round"], m["phase"]) for m in runlog.read_metrics(workdir)}
  try:
    base = round0_dir(config, workdir)
    demos, norm, state = round0(exp)
    for phase in ("fit", "evaluate"):
      if (0, phase) not in logged:
        log.write(_line(_read_json(os.path.join(base, f"{phase}.json")), config.explore.method))
    selected = []  # (episodes, round) of rounds done
    for r in range(1, int(config.rounds.num_rounds) + 1):
      rdir = os.path.join(workdir, "rounds", str(r))
      os.makedirs(rdir, exist_ok=True)
      data_path = os.path.join(workdir, "data", f"round_{r}.hdf5")
      explore_path = os.path.join(rdir, "explore.json")
      if not os.path.exists(explore_path):
        buf = build_buffer(config, exp.policy, [(demos, 0)] + selected)
        (rec, episodes), times = exp.timed(lambda: exp.explore(state, r, buf))
        hdf5.write_episodes(
          data_path,
          episodes,
          dict(env_name=exp.env.name, source=f"round {r} exploration", strategy=config.explore.strategy),
        )
        _write_json(explore_path, dict(rec, round=r, phase="explore", **times))
      rec = _read_json(explore_path)
      if (r, "explore") not in logged:
        log.write(_line(rec, config.explore.method))
      episodes = hdf5.read_episodes(data_path)[0] if rec["num_episodes"] else []
      selected.append((episodes, r))
      fit_path, ckpt = os.path.join(rdir, "fit.json"), os.path.join(rdir, "ckpt")
      if not os.path.exists(fit_path):
        sets = [(demos, 0)] + selected + steered_episodes(workdir, r)
        buf = build_buffer(config, exp.policy, sets)
        init = state if config.rounds.refit == "continue" else None
        (state, info), times = exp.timed(lambda: exp.fit(buf, norm, r, init))
        checkpoint.save(ckpt, state, config)
        _write_json(fit_path, dict(info, round=r, phase="fit", num_episodes=sum(len(e[0]) for e in sets), **times))
      else:
        state = checkpoint.load(ckpt).state
      if (r, "fit") not in logged:
        log.write(_line(_read_json(fit_path), config.explore.method))
      eval_path = os.path.join(rdir, "evaluate.json")
      if not os.path.exists(eval_path):
        rec, times = exp.timed(lambda: exp.evaluate(state, r))
        _write_json(eval_path, dict(rec, round=r, phase="evaluate", **times))
      if (r, "evaluate") not in logged:
        log.write(_line(_read_json(eval_path), config.explore.method))
  finally:
    log.close()
    exp.timer.close()
  return report.write(workdir)
