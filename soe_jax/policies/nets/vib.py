"""The VIB bypass networks: p_theta (conditioning -> latent mean, log-std) and q_phi (latent -> conditioning),
each a 3-layer ReLU MLP."""

from __future__ import annotations

import flax.linen as nn
import jax
import jax.numpy as jnp

from soe_jax.policies.nets.layers import Dense

LOG_STD_MIN, LOG_STD_MAX = -10.0, 4.0


class Encoder(nn.Module):
  """p_theta: (B, G) -> mu (B, d), log_std (B, d)."""

  latent_dim: int = 16
  hidden: int = 256

  @nn.compact
  def __call__(self, c):
    h = jax.nn.relu(Dense(self.hidden)(c))
    h = jax.nn.relu(Dense(self.hidden)(h))
    out = Dense(2 * self.latent_dim)(h)
    mu, log_std = jnp.split(out, 2, axis=-1)
    return mu, jnp.clip(log_std, LOG_STD_MIN, LOG_STD_MAX)


class Decoder(nn.Module):
  """q_phi: (B, d) -> (B, G)."""

  cond_dim: int
  hidden: int = 256

  @nn.compact
  def __call__(self, z):
    h = jax.nn.relu(Dense(self.hidden)(z))
    h = jax.nn.relu(Dense(self.hidden)(h))
    return Dense(self.cond_dim)(h)


def kl_standard_normal(mu, log_std):
  """KL(N(mu, sigma^2) || N(0, I)) summed over the latent, (B,)."""
  return 0.5 * jnp.sum(mu**2 + jnp.exp(2 * log_std) - 1.0 - 2.0 * log_std, axis=-1)
