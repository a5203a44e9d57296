"""The fit phase: SGD steps in compiled chunks (a `lax.scan` of `chunk_size` steps per call) over
windows sampled on device from the episode buffer; Python between chunks for the progress bar and the
non-finite check. Data parallel over all devices: the batch is sharded along `data`, the parameters
replicated; with the same keys the batch, and so the loss curve, is the same on any device count."""

from __future__ import annotations

import functools
import time

import jax
import jax.numpy as jnp
import ml_collections
import numpy as np
import optax
import tqdm

from soe_jax.data import buffer as buffer_lib
from soe_jax.policies.policy import Policy
from soe_jax.runtime import sharding
from soe_jax.train import train_state


class NonFiniteLossError(FloatingPointError):
  """Training produced a non-finite loss. The state passed in was donated to the compiled chunks, so
  what survives is the last checkpoint the caller wrote."""


def in_frame(raw: dict, frame=None) -> dict:
  """Sampled windows {"obs", "actions"} in the policy's frame (`frame`, a `frames.PoseLayout`, for
  relative poses; None: as recorded), still raw."""
  if frame is None:
    return raw
  obs, actions = raw["obs"], raw["actions"]
  lowdim = obs["lowdim"] if isinstance(obs, dict) else obs
  actions = frame.to_relative(lowdim, actions)
  obs = dict(obs, lowdim=frame.observe(lowdim)) if isinstance(obs, dict) else frame.observe(obs)
  return {"obs": obs, "actions": actions}


def training_batch(norm, raw: dict, frame=None) -> dict:
  """The batch the loss sees: sampled windows in the policy's frame (`in_frame`), normalised."""
  raw = in_frame(raw, frame)
  return {"obs": norm.normalize_obs(raw["obs"]), "actions": norm.normalize_actions(raw["actions"])}


def make_train_step(
  policy: Policy,
  tx: optax.GradientTransformation,
  batch_size: int,
  mesh,
  sampling: buffer_lib.Sampling = buffer_lib.UNIFORM,
):
  data = sharding.batch_sharded(mesh)

  def train_step(state: train_state.TrainState, buf: buffer_lib.EpisodeBuffer, key):
    key_batch, key_loss = jax.random.split(key)
    raw = buffer_lib.sample_windows(
      buf, key_batch, batch_size, policy.horizon, policy.n_obs_steps, policy.n_action_steps, sampling
    )
    norm = state.normalizer
    raw = in_frame(raw, policy.frame)
    batch = jax.lax.with_sharding_constraint(training_batch(norm, raw), data)
    (loss, aux), grads = jax.value_and_grad(policy.loss, has_aux=True)(state.params, batch, key_loss)
    updates, opt_state = tx.update(grads, state.opt_state, state.params)
    params = optax.apply_updates(state.params, updates)
    step = state.step + 1
    ema = state.ema_params
    if ema is not None:
      ema = train_state.ema_update(ema, params, train_state.ema_decay(step))
    metrics = dict(
      aux, loss=loss, grad_norm=optax.tree.norm(grads), obs_out_of_range=norm.out_of_range_fraction(raw["obs"])
    )
    return state.replace(step=step, params=params, ema_params=ema, opt_state=opt_state), metrics

  return train_step


@functools.lru_cache(maxsize=16)
def _chunk_fn(policy: Policy, tx, batch_size: int, length: int, mesh, sampling: buffer_lib.Sampling):
  train_step = make_train_step(policy, tx, batch_size, mesh, sampling)

  @functools.partial(jax.jit, donate_argnums=0)
  def chunk(state, buf, key):
    def body(state, k):
      return train_step(state, buf, k)

    state, metrics = jax.lax.scan(body, state, jax.random.split(key, length))
    return state, jax.tree.map(jnp.mean, metrics) | {"last_loss": metrics["loss"][-1]}

  return chunk


def fit(
  policy: Policy,
  tx: optax.GradientTransformation,
  state: train_state.TrainState,
  buf: buffer_lib.EpisodeBuffer,
  key,
  num_steps: int,
  config: ml_collections.ConfigDict,
  progress: bool = True,
  desc: str = "fit",
  start: int = 0,
  history: list[dict] | None = None,
  on_chunk=None,
  sampling: buffer_lib.Sampling = buffer_lib.UNIFORM,
):
  """Run SGD steps `start`..`num_steps` -> (state, per-chunk metrics list: the chunk's mean metrics,
  `step` after it, `chunk_s` its wall time with any compiling). `config`: batch_size,
  chunk_size. The batches depend only on `key` and the step, so a fit resumed from the state and
  history saved after step `start` ends as an uninterrupted one does; `on_chunk(state, done,
  history)` is called after every chunk (to save such a point). `sampling`: how batches are drawn
  (`buffer.Sampling`; Diffusion Policy's uniform draw by default).

  Raises NonFiniteLossError between chunks if the loss is not finite."""
  mesh = sharding.data_mesh()
  if config.batch_size % mesh.size:
    raise ValueError(f"batch_size {config.batch_size} is not divisible by the {mesh.size} devices")
  rep = sharding.replicated(mesh)
  state, buf = jax.device_put(state, rep), jax.device_put(buf, rep)
  history = list(history or [])
  done = start
  bar = tqdm.tqdm(total=num_steps, initial=done, desc=desc, unit="step", disable=not progress, leave=False)
  while done < num_steps:
    length = min(config.chunk_size, num_steps - done)
    t = time.perf_counter()
    chunk = _chunk_fn(policy, tx, int(config.batch_size), int(length), mesh, sampling)
    new_state, metrics = chunk(state, buf, jax.random.fold_in(key, done))
    metrics = {k: float(v) for k, v in jax.device_get(metrics).items()}
    if not all(np.isfinite(v) for v in metrics.values()):
      raise NonFiniteLossError(f"non-finite training metrics after step {done + length}: {metrics}")
    state = new_state
    done += length
    history.append(dict(metrics, step=done, chunk_s=round(time.perf_counter() - t, 3)))
    bar.update(length)
    bar.set_postfix(loss=f"{metrics['loss']:.4f}")
    if on_chunk is not None:
      on_chunk(state, done, history)
  bar.close()
  return state, history
