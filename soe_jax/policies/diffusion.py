"""DDPM noise schedule and samplers as Diffusion Policy uses them through diffusers 0.11
(`shared/specs/diffusion_policy.md` 2): squaredcos_cap_v2 with 100 training steps, epsilon prediction,
fixed-small variance, sample clipping to [-1, 1]; DDIM with set_alpha_to_one and steps_offset 0.

Samplers are `lax.scan` loops, so a whole chunk is one compiled call. `denoise(x, t, cond) -> eps`
is the noise predictor with `t` of shape (B,). Every sampler takes an optional conditioning hook
`cond_fn(cond, step_index, key) -> cond`, applied before each denoising call (SIME uses it).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

CondFn = Callable[[jax.Array, jax.Array, jax.Array], jax.Array]


def squaredcos_cap_v2(num_train_timesteps: int = 100) -> np.ndarray:
  """betas (T,) float64: beta_i = min(1 - abar((i+1)/T) / abar(i/T), 0.999)."""
  abar = lambda s: math.cos((s + 0.008) / 1.008 * math.pi / 2) ** 2
  t = num_train_timesteps
  return np.array([min(1 - abar((i + 1) / t) / abar(i / t), 0.999) for i in range(t)], np.float64)


@struct.dataclass
class Schedule:
  betas: jax.Array
  alphas_cumprod: jax.Array
  num_train_timesteps: int = struct.field(pytree_node=False, default=100)

  @classmethod
  def create(cls, num_train_timesteps: int = 100) -> Schedule:
    betas = squaredcos_cap_v2(num_train_timesteps)
    return cls(
      betas=jnp.asarray(betas, jnp.float32),
      alphas_cumprod=jnp.asarray(np.cumprod(1 - betas), jnp.float32),
      num_train_timesteps=num_train_timesteps,
    )

  def add_noise(self, x0: jax.Array, eps: jax.Array, t: jax.Array) -> jax.Array:
    ab = self.alphas_cumprod[t].reshape(t.shape + (1,) * (x0.ndim - t.ndim))
    return jnp.sqrt(ab) * x0 + jnp.sqrt(1 - ab) * eps


def _apply(cond_fn: CondFn | None, cond, i, key):
  return cond if cond_fn is None else cond_fn(cond, i, key)


def ddpm_sample(
  denoise, schedule: Schedule, cond, shape, key, cond_fn: CondFn | None = None, clip: bool = True
) -> jax.Array:
  """All training timesteps, T-1 .. 0 (diffusers DDPMScheduler, fixed_small)."""
  key_init, key_loop = jax.random.split(key)
  x = jax.random.normal(key_init, shape)
  ac = schedule.alphas_cumprod
  steps = jnp.arange(schedule.num_train_timesteps)[::-1]

  def step(x, inputs):
    i, t = inputs
    key_cond, key_noise = jax.random.split(jax.random.fold_in(key_loop, i))
    eps = denoise(x, jnp.full(shape[:1], t), _apply(cond_fn, cond, i, key_cond))
    ab_t = ac[t]
    ab_prev = jnp.where(t > 0, ac[jnp.maximum(t - 1, 0)], 1.0)
    beta_t = 1 - ab_t / ab_prev
    x0 = (x - jnp.sqrt(1 - ab_t) * eps) / jnp.sqrt(ab_t)
    x0 = jnp.clip(x0, -1, 1) if clip else x0
    mean = (jnp.sqrt(ab_prev) * beta_t / (1 - ab_t)) * x0 + (jnp.sqrt(1 - beta_t) * (1 - ab_prev) / (1 - ab_t)) * x
    var = jnp.maximum((1 - ab_prev) / (1 - ab_t) * beta_t, 1e-20)
    noise = jax.random.normal(key_noise, shape)
    return mean + jnp.where(t > 0, jnp.sqrt(var), 0.0) * noise, None

  x, _ = jax.lax.scan(step, x, (jnp.arange(steps.shape[0]), steps))
  return x


def ddim_timesteps(num_train_timesteps: int, num_steps: int) -> np.ndarray:
  """diffusers DDIM (steps_offset 0): (arange(num_steps) * (T // num_steps))[::-1]."""
  return (np.arange(num_steps) * (num_train_timesteps // num_steps))[::-1].astype(np.int32)


def ddim_sample(
  denoise,
  schedule: Schedule,
  cond,
  shape,
  key,
  num_steps: int = 10,
  eta: float = 0.0,
  cond_fn: CondFn | None = None,
  clip: bool = True,
) -> jax.Array:
  """diffusers DDIMScheduler.step with set_alpha_to_one: x0 clipped, the direction uses the raw eps."""
  key_init, key_loop = jax.random.split(key)
  x = jax.random.normal(key_init, shape)
  ac = schedule.alphas_cumprod
  stride = schedule.num_train_timesteps // num_steps
  steps = jnp.asarray(ddim_timesteps(schedule.num_train_timesteps, num_steps))

  def step(x, inputs):
    i, t = inputs
    key_cond, key_noise = jax.random.split(jax.random.fold_in(key_loop, i))
    eps = denoise(x, jnp.full(shape[:1], t), _apply(cond_fn, cond, i, key_cond))
    prev = t - stride
    ab_t = ac[t]
    ab_prev = jnp.where(prev >= 0, ac[jnp.maximum(prev, 0)], 1.0)
    x0 = (x - jnp.sqrt(1 - ab_t) * eps) / jnp.sqrt(ab_t)
    x0 = jnp.clip(x0, -1, 1) if clip else x0
    var = (1 - ab_prev) / (1 - ab_t) * (1 - ab_t / ab_prev)
    std = eta * jnp.sqrt(var)
    direction = jnp.sqrt(jnp.maximum(1 - ab_prev - std**2, 0.0)) * eps
    x = jnp.sqrt(ab_prev) * x0 + direction
    if eta > 0:
      x = x + std * jax.random.normal(key_noise, shape)
    return x, None

  x, _ = jax.lax.scan(step, x, (jnp.arange(num_steps), steps))
  return x
