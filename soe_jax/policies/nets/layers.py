"""Layers with PyTorch's parameterisation and default initialisation, written for XLA:CPU speed.

`Conv1d` is an im2col gather plus one matrix product: XLA:CPU takes a slow path (a few GFLOP/s) for a
1-D convolution whose kernel is longer than its input (kernel 5 on the UNet's 4-step deepest level),
while a matrix product runs at full speed. `ConvTranspose1d` (kernel 4, stride 2, padding 1) is
written in polyphase form, four matrix products over x[m-1], x[m], x[m+1], because the backward pass
of XLA's transposed convolution is very slow on CPU. Both keep PyTorch's parameter count.

Weights are stored (out, in) as PyTorch does, and products contract over the minor axis of both
operands: measured here, XLA:CPU reads weights about twice as fast that way when a batch has few
rows (sampling one observation), and equally fast for training batches.
Tensors are channels-last: (B, T, C).
"""

from __future__ import annotations

import flax.linen as nn
import jax
import jax.numpy as jnp


def torch_uniform(fan_in: int):
  """PyTorch's default Linear/Conv init for weights and biases: U(-1/sqrt(fan_in), 1/sqrt(fan_in))."""
  bound = 1.0 / jnp.sqrt(fan_in)

  def init(key, shape, dtype=jnp.float32):
    return jax.random.uniform(key, shape, dtype, -bound, bound)

  return init


def mish(x):
  return x * jnp.tanh(jax.nn.softplus(x))


def _matmul_t(x, w):
  """x (..., K) times w (N, K) transposed -> (..., N)."""
  return jnp.einsum("...k,nk->...n", x, w)


class Dense(nn.Module):
  features: int

  @nn.compact
  def __call__(self, x):
    fan_in = x.shape[-1]
    w = self.param("kernel", torch_uniform(fan_in), (self.features, fan_in))
    b = self.param("bias", torch_uniform(fan_in), (self.features,))
    return _matmul_t(x, w) + b


class Conv1d(nn.Module):
  """Conv1d(in, features, kernel_size, stride, padding) on (B, T, C) as im2col + matmul."""

  features: int
  kernel_size: int
  stride: int = 1
  padding: int | None = None  # default: kernel_size // 2 (length preserved at stride 1)

  @nn.compact
  def __call__(self, x):
    k, c = self.kernel_size, x.shape[-1]
    pad = self.kernel_size // 2 if self.padding is None else self.padding
    fan_in = c * k
    w = self.param("kernel", torch_uniform(fan_in), (self.features, c, k))  # PyTorch's Conv1d layout
    b = self.param("bias", torch_uniform(fan_in), (self.features,))
    if k == 1 and self.stride == 1 and pad == 0:
      return _matmul_t(x, w[:, :, 0]) + b
    t_out = (x.shape[-2] + 2 * pad - k) // self.stride + 1
    xp = jnp.pad(x, [(0, 0)] * (x.ndim - 2) + [(pad, pad), (0, 0)])
    cols = [xp[..., i : i + self.stride * (t_out - 1) + 1 : self.stride, :] for i in range(k)]
    patches = jnp.stack(cols, axis=-1).reshape(x.shape[:-2] + (t_out, c * k))  # (B, T_out, C * k)
    return _matmul_t(patches, w.reshape(self.features, c * k)) + b


class ConvTranspose1d(nn.Module):
  """ConvTranspose1d(C, C, kernel 4, stride 2, padding 1): (B, T, C) -> (B, 2T, C), polyphase.

  y[2m] = x[m] W1 + x[m-1] W3 and y[2m+1] = x[m+1] W0 + x[m] W2 (zero outside the input)."""

  features: int

  @nn.compact
  def __call__(self, x):
    c = x.shape[-1]
    # PyTorch's ConvTranspose1d fan_in is computed from weight dim 1 (out channels) * kernel.
    fan_in = self.features * 4
    w = self.param("kernel", torch_uniform(fan_in), (4, self.features, c))  # tap-major, (out, in) per tap
    b = self.param("bias", torch_uniform(fan_in), (self.features,))
    pad = [(0, 0)] * (x.ndim - 2)
    x_prev = jnp.pad(x[..., :-1, :], pad + [(1, 0), (0, 0)])
    x_next = jnp.pad(x[..., 1:, :], pad + [(0, 1), (0, 0)])
    even = _matmul_t(x, w[1]) + _matmul_t(x_prev, w[3])
    odd = _matmul_t(x_next, w[0]) + _matmul_t(x, w[2])
    y = jnp.stack([even, odd], axis=-2)  # (B, T, 2, F)
    return y.reshape(x.shape[:-2] + (2 * x.shape[-2], self.features)) + b


class GroupNorm(nn.Module):
  """GroupNorm with PyTorch's eps (1e-5) and affine init (ones, zeros)."""

  num_groups: int = 8
  eps: float = 1e-5

  @nn.compact
  def __call__(self, x):
    return nn.GroupNorm(num_groups=self.num_groups, epsilon=self.eps)(x)
