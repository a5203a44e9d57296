"""Observation encoders E: normalised observation history -> conditioning vector `c`.

- `lowdim`: the normalised low-dim vectors of the `n_obs_steps` frames, concatenated oldest first
  (no parameters), (B, To, D) -> (B, To * D).
- `image`: robomimic's ResNet-18 (GroupNorm) + spatial-softmax encoder per camera, concatenated with
  the low-dim vector per frame (`resnet.py`); observations are then a dict {"images", "lowdim"}.
"""

from __future__ import annotations

import flax.linen as nn

from soe_jax.policies.nets.resnet import ImageEncoder


class LowDimEncoder(nn.Module):
  @nn.compact
  def __call__(self, obs, train: bool = False):
    return obs.reshape(obs.shape[:-2] + (obs.shape[-2] * obs.shape[-1],))


ENCODERS = {"lowdim": LowDimEncoder, "image": ImageEncoder}


def make_encoder(name: str, **kwargs) -> nn.Module:
  if name not in ENCODERS:
    raise ValueError(f"unknown observation encoder {name!r}; known: {', '.join(sorted(ENCODERS))}")
  return ENCODERS[name](**kwargs)
