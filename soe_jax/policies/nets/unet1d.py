"""ConditionalUnet1D exactly as Diffusion Policy builds it (`shared/specs/diffusion_policy.md` 1).

Sinusoidal step embedding + MLP; FiLM (scale * h + bias, no "1 +"); Conv1d-GroupNorm-Mish blocks;
down levels of two residual blocks each with a stride-2 downsample except the last; two mid blocks;
one fewer up stage than down levels, each concatenating a skip (the finest level's skip is never used)
and always upsampling; a final Conv1dBlock and 1x1 Conv1d. Channels-last: (B, T, A) in and out.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import flax.linen as nn
import jax.numpy as jnp

from soe_jax.policies.nets.layers import Conv1d, ConvTranspose1d, Dense, GroupNorm, mish


def sinusoidal_embedding(t, dim: int):
  """(B,) integer (or real) steps -> (B, dim): [sin(t f_k), cos(t f_k)], f_k = exp(-k ln(1e4)/(half-1))."""
  half = dim // 2
  freqs = jnp.exp(-jnp.arange(half) * (math.log(10000.0) / (half - 1)))
  args = jnp.asarray(t, jnp.float32)[..., None] * freqs
  return jnp.concatenate([jnp.sin(args), jnp.cos(args)], axis=-1)


class Conv1dBlock(nn.Module):
  features: int
  kernel_size: int
  n_groups: int = 8

  @nn.compact
  def __call__(self, x):
    return mish(GroupNorm(self.n_groups)(Conv1d(self.features, self.kernel_size)(x)))


class ResidualBlock(nn.Module):
  features: int
  kernel_size: int
  n_groups: int = 8

  @nn.compact
  def __call__(self, x, cond):
    h = Conv1dBlock(self.features, self.kernel_size, self.n_groups)(x)
    film = Dense(2 * self.features)(mish(cond))  # (B, 2 * out): scale then bias
    scale, bias = film[..., None, : self.features], film[..., None, self.features :]
    h = scale * h + bias
    h = Conv1dBlock(self.features, self.kernel_size, self.n_groups)(h)
    residual = Conv1d(self.features, 1)(x) if x.shape[-1] != self.features else x
    return h + residual


class ConditionalUnet1D(nn.Module):
  """eps or velocity predictor: (sample (B, T, A), step (B,), global_cond (B, G)) -> (B, T, A)."""

  down_dims: Sequence[int] = (256, 512, 1024)
  step_embed_dim: int = 256
  kernel_size: int = 5
  n_groups: int = 8

  @nn.compact
  def __call__(self, sample, step, global_cond):
    input_dim = sample.shape[-1]
    dsed = self.step_embed_dim
    emb = sinusoidal_embedding(jnp.broadcast_to(step, sample.shape[:1]), dsed)
    emb = Dense(dsed)(mish(Dense(4 * dsed)(emb)))
    cond = jnp.concatenate([emb, global_cond], axis=-1) if global_cond is not None else emb
    block = lambda f: ResidualBlock(f, self.kernel_size, self.n_groups)

    x = sample
    skips = []
    dims = list(self.down_dims)
    for i, d in enumerate(dims):
      x = block(d)(x, cond)
      x = block(d)(x, cond)
      skips.append(x)
      if i < len(dims) - 1:
        x = Conv1d(d, 3, stride=2, padding=1)(x)
    x = block(dims[-1])(x, cond)
    x = block(dims[-1])(x, cond)
    in_dims = [input_dim] + dims[:-1]
    for level in reversed(range(1, len(dims))):  # reversed(in_out[1:]): (in_dims[level], dims[level])
      x = jnp.concatenate([x, skips[level]], axis=-1)
      x = block(in_dims[level])(x, cond)
      x = block(in_dims[level])(x, cond)
      x = ConvTranspose1d(in_dims[level])(x)
    x = Conv1dBlock(dims[0], self.kernel_size, self.n_groups)(x)
    return Conv1d(input_dim, 1)(x)
