"""One round's fit, wherever its episodes come from: the simulated run's (`experiment.phases`) and a
robot's (`robot.run`) fit through this one path, so that the same episodes under the same config give
the same parameters on both. Nothing here needs a simulator.

A round's fit starts from fresh parameters (round 0, or a re-fit from scratch) for `fit.num_steps` at
`fit.lr`, or continues from the previous round's state (`init_state`) for `rounds.refit_steps` at
`rounds.refit_lr` (0: `fit.lr`) with its EMA restarted or carried on (`rounds.refit_ema`). Re-fits draw
their windows as `rounds.demo_fraction` and `rounds.aligned_windows` say (`sampling`). Before any step
every training target is checked against the normaliser's box (`action_box`); a fit in progress is
saved every `fit.checkpoint_every` steps and on the first Ctrl-C, and resumes from the newest save
(`partial.PartialFit`); keys are fold_in(seed, round, FIT).
"""

from __future__ import annotations

import time

import jax
import jax.numpy as jnp
import ml_collections

from soe_jax.data import buffer as buffer_lib
from soe_jax.data.episodes import EpisodeSet, build_buffer
from soe_jax.data.spec import PolicySpec
from soe_jax.policies.policy import Policy
from soe_jax.runtime import interrupt
from soe_jax.runtime.console import between_bars, duration
from soe_jax.train import action_box, checkpoint, train_state
from soe_jax.train import fit as fit_lib
from soe_jax.train.partial import PartialFit

FIT = 1  # a round's key stream for its fit: fold_in(fold_in(key(seed), r), FIT)
# The last chunk's mean of each loss term kept in the record (the bypass's KL and IB head loss among them).
FINAL_METRICS = ("loss_il", "loss_ib", "loss_ib_head", "kl", "latent_std")


def round_key(seed: int, r: int, stream: int) -> jax.Array:
  """Round r's key of `stream`: fold_in(fold_in(key(seed), r), stream)."""
  return jax.random.fold_in(jax.random.fold_in(jax.random.key(int(seed)), r), stream)


def sampling(config: ml_collections.ConfigDict, r: int) -> buffer_lib.Sampling:
  """How round r's fit draws its windows: round 0 holds the demonstrations alone, drawn uniformly;
  re-fits as `rounds.demo_fraction` and `rounds.aligned_windows` say."""
  if not r:
    return buffer_lib.UNIFORM
  return buffer_lib.Sampling(float(config.rounds.demo_fraction), bool(config.rounds.aligned_windows))


class RoundFit:
  """The fits of one policy under one config. One optimiser object per schedule, so that later rounds
  reuse the compiled fit chunks."""

  def __init__(self, policy: Policy, config: ml_collections.ConfigDict, spec: PolicySpec):
    self.policy, self.config, self.spec = policy, config, spec
    self._optimizers = {}

  def optimizer(self, steps: int, lr: float):
    if (steps, lr) not in self._optimizers:
      self._optimizers[steps, lr] = train_state.make_optimizer(self.config.fit, steps, lr)
    return self._optimizers[steps, lr]

  def data(self, sets: list[EpisodeSet], norm, path_of, env=None) -> tuple[buffer_lib.EpisodeBuffer, float]:
    """(the training buffer of `sets`, the fraction of their actions outside the normaliser's box).
    A target outside a stated box is a `UserError` naming `path_of(set)`'s file; under the
    demonstrations' range it is counted (and clipped in training). `env` draws the images an image
    policy's episodes lack."""
    c = self.config
    clipped = action_box.check(sets, norm, self.spec, c.policy.action_range, path_of, self.policy)
    return build_buffer(c, self.policy, sets, env), clipped

  def fit(self, buf, norm, r: int, partial: PartialFit, init_state=None, steps: int | None = None,
          progress: bool = True, evaluate=None) -> tuple[train_state.TrainState, dict]:  # fmt: skip
    """Round r's fit on `buf` -> (the TrainState, its record: steps, the loss curve, the last chunk's
    loss terms, the steps' time without evaluations). `steps` overrides the number of steps.
    `evaluate(state) -> {"success": ...}`, with `fit.eval_every`: the EMA policy evaluated along the
    way (`eval_curve` in the record)."""
    c = self.config
    key = round_key(c.seed, r, FIT)
    if init_state is None:
      steps, lr = int(steps or c.fit.num_steps), float(c.fit.lr)
      params = self.policy.init(jax.random.fold_in(key, 0))
    else:
      steps, lr = int(steps or c.rounds.refit_steps), float(c.rounds.refit_lr or c.fit.lr)
      params = init_state.params
    tx = self.optimizer(steps, lr)
    # fit donates its input state: build it from copies, so `norm` and `init_state` stay usable.
    state = jax.tree.map(jnp.copy, train_state.create(params, tx, norm, ema=c.fit.ema))
    if init_state is not None and c.rounds.refit_ema == "carry" and init_state.ema_params is not None:
      # The EMA goes on from the previous fit's (its step too, so its decay does), as one long fit's would.
      state = state.replace(ema_params=jax.tree.map(jnp.copy, init_state.ema_params), step=jnp.copy(init_state.step))
    start, history = 0, []
    if (saved := partial.restore(checkpoint.abstract_state(c, self.policy))) is not None:  # an interrupted fit
      state, start, history = saved
    chunk = int(c.fit.chunk_size)
    chunks = lambda every: max(1, int(every) // chunk) if every else 0
    save_every = chunks(c.fit.checkpoint_every)
    eval_every = chunks(c.fit.eval_every) if evaluate is not None else 0
    with interrupt.deferred("stopping: saving the fit after the chunk in progress (again to stop now)") as stop:

      def on_chunk(state, done, history):
        n = done // chunk
        if done == start + 2 * chunk and done < steps:  # the first chunk compiled; the second ran
          pace = history[-1]["chunk_s"] / chunk
          between_bars(f"round {r} fit: {1000 * pace:.0f} ms per step, about {duration(pace * (steps - done))} "
                       f"left of {steps:,} steps")  # fmt: skip
        if eval_every and (n % eval_every == 0 or done == steps):
          t = time.perf_counter()
          ev = evaluate(state)
          history[-1].update(eval_success=ev["success"], eval_s=round(time.perf_counter() - t, 3))
        if stop or (save_every and done < steps and n % save_every == 0):
          partial.save(state, done, history)
        if stop:
          raise KeyboardInterrupt

      state, history = fit_lib.fit(self.policy, tx, state, buf, jax.random.fold_in(key, 1), steps, c.fit, progress,
                                   f"round {r} fit", start, history, on_chunk, sampling(c, r))  # fmt: skip
    info = dict(steps=steps, final_loss=history[-1]["loss"], loss_curve=[h["loss"] for h in history])
    info["final_metrics"] = {k: history[-1][k] for k in FINAL_METRICS if k in history[-1]}
    info["time_steps_s"] = round(sum(h.get("chunk_s", 0.0) for h in history), 2)  # without in-fit evaluations
    if eval_every:
      info["eval_curve"] = eval_curve(history)
    return state, info

  def save(self, ckpt_dir: str, state, partial: PartialFit) -> None:
    """The fitted round's checkpoint, then its fit in progress removed."""
    checkpoint.save(ckpt_dir, state, self.config, self.spec)
    partial.clear()


def eval_curve(history: list[dict]) -> list[dict]:
  """The in-fit evaluations of a fit's history: step, success rate, the per-state outcomes, and the fit's
  time up to then without (`fit_s`) and with (`wall_s`) the evaluations before."""
  curve, fit_s, eval_s = [], 0.0, 0.0
  for h in history:
    fit_s += h.get("chunk_s", 0.0)
    if "eval_success" in h:
      outcomes = h["eval_success"]
      curve.append(dict(step=h["step"], success_rate=sum(outcomes) / len(outcomes), success=outcomes,
                        fit_s=round(fit_s, 2), wall_s=round(fit_s + eval_s, 2)))  # fmt: skip
      eval_s += h["eval_s"]
  return curve
