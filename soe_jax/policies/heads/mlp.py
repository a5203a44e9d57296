"""`mlp`: deterministic regression of the whole action chunk from the conditioning (MSE)."""

from __future__ import annotations

from collections.abc import Sequence

import flax.linen as nn
import jax
import jax.numpy as jnp

from soe_jax.policies.heads.base import Head
from soe_jax.policies.nets.layers import Dense


class ChunkMLP(nn.Module):
  hidden: Sequence[int]
  out: int

  @nn.compact
  def __call__(self, x):
    for h in self.hidden:
      x = jax.nn.relu(Dense(h)(x))
    return Dense(self.out)(x)


def make(action_dim: int, horizon: int, hidden: Sequence[int] = (1024, 1024)) -> Head:
  net = ChunkMLP(tuple(hidden), horizon * action_dim)

  def predict(params, cond):
    return jnp.tanh(net.apply({"params": params}, cond)).reshape(cond.shape[:1] + (horizon, action_dim))

  def init(key, cond_dim):
    return net.init(key, jnp.zeros((1, cond_dim)))["params"]

  def loss(params, cond, actions, key):
    del key
    return jnp.mean((predict(params, cond) - actions) ** 2), {}

  def sample(params, cond, key, cond_fn=None):
    c = cond if cond_fn is None else cond_fn(cond, jnp.array(0), key)
    return predict(params, c), {}

  def progress(step_index):  # one call, straight to the data
    return jnp.ones((), jnp.float32)

  return Head("mlp", action_dim, horizon, init, loss, sample, progress, net)
