"""`diffusion_unet`: Diffusion Policy's ConditionalUnet1D noise predictor, DDPM training (epsilon MSE),
DDIM (default, 10 steps) or DDPM (100 steps) sampling with clipping."""

from __future__ import annotations

from collections.abc import Sequence

import jax
import jax.numpy as jnp

from soe_jax.policies import diffusion
from soe_jax.policies.heads.base import Head
from soe_jax.policies.nets.unet1d import ConditionalUnet1D

SAMPLERS = ("ddim", "ddpm")


def make(
  action_dim: int,
  horizon: int,
  down_dims: Sequence[int] = (256, 512, 1024),
  step_embed_dim: int = 256,
  kernel_size: int = 5,
  n_groups: int = 8,
  num_train_timesteps: int = 100,
  sampler: str = "ddim",
  num_inference_steps: int = 10,
  eta: float = 0.0,
) -> Head:
  if sampler not in SAMPLERS:
    raise ValueError(f"unknown sampler {sampler!r}; known: {', '.join(SAMPLERS)}")
  net = ConditionalUnet1D(
    down_dims=tuple(down_dims), step_embed_dim=step_embed_dim, kernel_size=kernel_size, n_groups=n_groups
  )
  schedule = diffusion.Schedule.create(num_train_timesteps)
  shape = (horizon, action_dim)

  def init(key, cond_dim):
    return net.init(key, jnp.zeros((1,) + shape), jnp.zeros((1,), jnp.int32), jnp.zeros((1, cond_dim)))["params"]

  def loss(params, cond, actions, key):
    key_t, key_eps = jax.random.split(key)
    b = actions.shape[0]
    t = jax.random.randint(key_t, (b,), 0, num_train_timesteps)
    eps = jax.random.normal(key_eps, actions.shape)
    pred = net.apply({"params": params}, schedule.add_noise(actions, eps, t), t, cond)
    return jnp.mean((pred - eps) ** 2), {}

  def sample(params, cond, key, cond_fn=None):
    denoise = lambda x, t, c: net.apply({"params": params}, x, t, c)
    out_shape = (cond.shape[0],) + shape
    if sampler == "ddim":
      x = diffusion.ddim_sample(denoise, schedule, cond, out_shape, key, num_inference_steps, eta, cond_fn)
    else:
      x = diffusion.ddpm_sample(denoise, schedule, cond, out_shape, key, cond_fn)
    return x, {}

  if sampler == "ddim":
    timesteps = jnp.asarray(diffusion.ddim_timesteps(num_train_timesteps, num_inference_steps))
  else:
    timesteps = jnp.arange(num_train_timesteps)[::-1]

  def progress(step_index):
    return 1.0 - jnp.clip(timesteps[step_index] / num_train_timesteps, 0.0, 1.0)

  return Head("diffusion_unet", action_dim, horizon, init, loss, sample, progress, net)
