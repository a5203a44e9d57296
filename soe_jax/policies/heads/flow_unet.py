"""`flow_unet`: flow matching (rectified flow) on the same ConditionalUnet1D backbone.

x_s = (1 - s) noise + s action for s ~ U[0, 1]; the network predicts the velocity action - noise
(its step input is 100 s, the range of the diffusion step embedding). Sampling integrates with a few
Euler steps from noise at s = 0 to s = 1, then clips to [-1, 1]."""

from __future__ import annotations

from collections.abc import Sequence

import jax
import jax.numpy as jnp

from soe_jax.policies.heads.base import Head
from soe_jax.policies.nets.unet1d import ConditionalUnet1D

TIME_SCALE = 100.0


def make(
  action_dim: int,
  horizon: int,
  down_dims: Sequence[int] = (256, 512, 1024),
  step_embed_dim: int = 256,
  kernel_size: int = 5,
  n_groups: int = 8,
  num_inference_steps: int = 10,
) -> Head:
  net = ConditionalUnet1D(
    down_dims=tuple(down_dims), step_embed_dim=step_embed_dim, kernel_size=kernel_size, n_groups=n_groups
  )
  shape = (horizon, action_dim)

  def init(key, cond_dim):
    return net.init(key, jnp.zeros((1,) + shape), jnp.zeros((1,)), jnp.zeros((1, cond_dim)))["params"]

  def loss(params, cond, actions, key):
    key_s, key_noise = jax.random.split(key)
    s = jax.random.uniform(key_s, (actions.shape[0],))
    noise = jax.random.normal(key_noise, actions.shape)
    x = (1 - s[:, None, None]) * noise + s[:, None, None] * actions
    pred = net.apply({"params": params}, x, TIME_SCALE * s, cond)
    return jnp.mean((pred - (actions - noise)) ** 2), {}

  def sample(params, cond, key, cond_fn=None):
    key_init, key_loop = jax.random.split(key)
    x = jax.random.normal(key_init, (cond.shape[0],) + shape)
    dt = 1.0 / num_inference_steps

    def step(x, i):
      c = cond if cond_fn is None else cond_fn(cond, i, jax.random.fold_in(key_loop, i))
      v = net.apply({"params": params}, x, jnp.full(x.shape[:1], TIME_SCALE * i * dt), c)
      return x + dt * v, None

    x, _ = jax.lax.scan(step, x, jnp.arange(num_inference_steps))
    return jnp.clip(x, -1, 1), {}

  def progress(step_index):  # the flow's time s runs from 0 (noise) to 1 (data)
    return jnp.asarray(step_index, jnp.float32) / num_inference_steps

  return Head("flow_unet", action_dim, horizon, init, loss, sample, progress, net)
