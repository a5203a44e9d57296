"""Observation encoders E: normalised observation history -> conditioning vector `c`.

- `lowdim`: the normalised low-dim vectors of the `n_obs_steps` frames, concatenated oldest first
  (no parameters), (B, To, D) -> (B, To * D).
- `image`: robomimic's ResNet-18 (GroupNorm) + spatial-softmax encoder per camera, concatenated with
  the low-dim vector per frame (`resnet.py`); observations are then a dict {"images", "lowdim"}.
"""

from __future__ import annotations

import flax.linen as nn

from soe_jax.policies.nets.resnet import ImageEncoder  # noqa: F401  (registered with LowDimEncoder)


class LowDimEncoder(nn.Module):
  @nn.compact
  def __call__(self, obs, train: bool = False):
    return obs.reshape(obs.shape[:-2] + (obs.shape[-2] * obs.shape[-1],))
