"""Heads and observation encoders by name (`policy.head.name`, `policy.encoder.name` in configs)."""

from __future__ import annotations

import flax.linen as nn

from soe_jax.policies.heads import diffusion_unet, flow_unet, mlp
from soe_jax.policies.heads.base import Head
from soe_jax.policies.nets import encoders
from soe_jax.registry import Registry

HEADS: Registry[Head] = Registry("head")
register_head = HEADS.register
head_names = HEADS.names
ENCODERS: Registry[nn.Module] = Registry("observation encoder")
register_encoder = ENCODERS.register


def make_head(name: str, action_dim: int, horizon: int, **kwargs) -> Head:
  return HEADS.make(name, action_dim=action_dim, horizon=horizon, **kwargs)


def make_encoder(name: str, **kwargs) -> nn.Module:
  # Sequences as tuples (a config read back from JSON has lists), so the module hashes.
  kwargs = {k: tuple(v) if isinstance(v, list) else v for k, v in kwargs.items()}
  return ENCODERS.make(name, **kwargs)


register_head("diffusion_unet", diffusion_unet.make)
register_head("flow_unet", flow_unet.make)
register_head("mlp", mlp.make)
register_encoder("lowdim", encoders.LowDimEncoder)
register_encoder("image", encoders.ImageEncoder)
