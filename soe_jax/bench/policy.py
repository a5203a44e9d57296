"""Policy benchmarks on random data in memory: fit-step time and one action chunk's sampling time.

`fit` times whole compiled chunks of SGD steps (window sampling from an episode buffer, normalisation,
forward, backward, AdamW, EMA when on) and reports the mean per step; `sample` times one base-path
action chunk (the configured sampler with `steps` denoising steps). An image policy's data hold
random uint8 images too (`--config=configs/TASK.py:image`)."""

from __future__ import annotations

import time

import jax
import jax.numpy as jnp
import ml_collections
import numpy as np

from soe_jax.data import buffer as buffer_lib
from soe_jax.experiment import task
from soe_jax.policies import normalizer as normalizer_lib
from soe_jax.train import fit as fit_lib
from soe_jax.train import train_state


def _param_count(tree) -> int:
  return int(sum(np.prod(x.shape) for x in jax.tree.leaves(tree)))


def _random_setup(config, key):
  policy = task.policy(config)
  obs_dim, action_dim = policy.obs_dim, policy.action_dim
  rng = np.random.default_rng(0)
  n, length = 64, 120
  obs = rng.uniform(-1, 1, (n, length, obs_dim)).astype(np.float32)
  actions = rng.uniform(-1, 1, (n, length, action_dim)).astype(np.float32)
  buf = buffer_lib.add(
    buffer_lib.create(n, length, obs_dim, action_dim), obs, actions, np.full(n, length), np.ones(n, bool), 0
  )
  if policy.image_keys:
    shape = (length,) + policy.example_obs["images"][policy.image_keys[0]].shape[2:]
    images = [{k: rng.integers(0, 256, shape, np.uint8) for k in policy.image_keys} for _ in range(n)]
    buf = buffer_lib.with_images(buf, images, n * length)
  norm = normalizer_lib.fit(obs.reshape(-1, obs_dim), actions.reshape(-1, action_dim))
  return policy, policy.init(key), buf, norm


def _zero_obs(policy, batch: int):
  """A batch of all-zero observation histories in the policy's form."""
  return jax.tree.map(lambda x: jnp.zeros((batch,) + x.shape[1:], x.dtype), policy.example_obs)


def fit(config: ml_collections.ConfigDict, bypass: bool, ema: bool, steps: int = 10, repeats: int = 2) -> dict:
  config = ml_collections.ConfigDict(config)
  config.policy.bypass.enabled = bypass
  policy, params, buf, norm = _random_setup(config, jax.random.key(0))
  tx = train_state.make_optimizer(config.fit, 10_000)
  state = train_state.create(params, tx, norm, ema=ema)
  fit_cfg = ml_collections.ConfigDict(dict(batch_size=config.fit.batch_size, chunk_size=steps))
  t = time.perf_counter()
  state, _ = fit_lib.fit(policy, tx, state, buf, jax.random.key(1), steps, fit_cfg, progress=False)
  compile_and_first = time.perf_counter() - t
  t = time.perf_counter()
  for r in range(repeats):
    state, _ = fit_lib.fit(policy, tx, state, buf, jax.random.key(2 + r), steps, fit_cfg, progress=False)
  jax.block_until_ready(state.params)
  per_step = (time.perf_counter() - t) / (steps * repeats)
  return dict(
    bench="fit",
    task=config.env.task,
    obs_encoder=config.policy.encoder.name,
    head=config.policy.head.name,
    down_dims=list(config.policy.head.kwargs.get("down_dims", [])),
    batch_size=config.fit.batch_size,
    bypass=bypass,
    ema=ema,
    ms_per_step=round(per_step * 1000, 2),
    samples_per_s=round(config.fit.batch_size / per_step, 1),
    params=_param_count(state.params),
    first_chunk_s=round(compile_and_first, 2),
    devices=jax.device_count(),
  )


def sample(config: ml_collections.ConfigDict, batch: int, steps: int, repeats: int = 20) -> dict:
  config = ml_collections.ConfigDict(config)
  if "num_inference_steps" in config.policy.head.kwargs:
    config.policy.head.kwargs.num_inference_steps = steps
  policy, params, _, _ = _random_setup(config, jax.random.key(0))
  obs = _zero_obs(policy, batch)
  fn = jax.jit(policy.sample)
  t = time.perf_counter()
  jax.block_until_ready(fn(params, obs, jax.random.key(0)))
  compile_s = time.perf_counter() - t
  times = []
  for r in range(repeats):
    t = time.perf_counter()
    jax.block_until_ready(fn(params, obs, jax.random.key(r)))
    times.append(time.perf_counter() - t)
  return dict(
    bench="sample",
    task=config.env.task,
    head=config.policy.head.name,
    down_dims=list(config.policy.head.kwargs.get("down_dims", [])),
    batch=batch,
    steps=steps,
    ms_per_chunk=round(float(np.median(times)) * 1000, 2),
    params=_param_count(params["head"]),
    compile_s=round(compile_s, 2),
  )
