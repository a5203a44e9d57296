"""ConditionalUnet1D: Diffusion Policy's parameter count, and the fast layers equal XLA's convolutions."""

import jax
import jax.numpy as jnp
import numpy as np

from soe_jax.policies.nets.layers import Conv1d, ConvTranspose1d
from soe_jax.policies.nets.unet1d import ConditionalUnet1D


def _count(module, *args):
  shapes = jax.eval_shape(module.init, jax.random.PRNGKey(0), *args)
  return sum(int(np.prod(x.shape)) for x in jax.tree.leaves(shapes))


def test_parameter_count_matches_diffusion_policy_lowdim_square():
  net = ConditionalUnet1D(down_dims=(256, 512, 1024), step_embed_dim=256, kernel_size=5, n_groups=8)
  assert _count(net, jnp.zeros((1, 16, 10)), jnp.zeros((1,)), jnp.zeros((1, 46))) == 65_883_658
  assert _count(net, jnp.zeros((1, 16, 10)), jnp.zeros((1,)), jnp.zeros((1, 38))) == 65_768_970  # lift


def test_im2col_conv_equals_xla_convolution():
  x = jax.random.normal(jax.random.PRNGKey(0), (2, 4, 6))  # kernel 5 longer than the input, as at the deepest level
  for k, stride, pad in ((5, 1, 2), (3, 2, 1), (1, 1, 0)):
    layer = Conv1d(7, k, stride=stride, padding=pad)
    params = layer.init(jax.random.PRNGKey(1), x)
    w, b = params["params"]["kernel"], params["params"]["bias"]  # PyTorch layout (out, in, k)
    ref = jax.lax.conv_general_dilated(x, w, (stride,), [(pad, pad)], dimension_numbers=("NWC", "OIW", "NWC")) + b
    np.testing.assert_allclose(layer.apply(params, x), ref, atol=1e-5)


def test_polyphase_upsample_equals_transposed_convolution():
  x = jax.random.normal(jax.random.PRNGKey(0), (2, 4, 6))
  layer = ConvTranspose1d(6)
  params = layer.init(jax.random.PRNGKey(1), x)
  w, b = params["params"]["kernel"], params["params"]["bias"]  # (k, out, in), PyTorch tap order
  # PyTorch ConvTranspose1d(k=4, stride=2, padding=1): dilate the input by 2, pad k-1-p = 2, flip the taps.
  ref = (
    jax.lax.conv_general_dilated(x, w[::-1], (1,), [(2, 2)], lhs_dilation=(2,), dimension_numbers=("NWC", "WOI", "NWC"))
    + b
  )
  out = layer.apply(params, x)
  assert out.shape == (2, 8, 6)
  np.testing.assert_allclose(out, ref, atol=1e-5)
