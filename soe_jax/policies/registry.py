"""Heads and observation encoders by name (`policy.head.name`, `policy.encoder.name` in configs)."""

from __future__ import annotations

from collections.abc import Callable

from soe_jax.policies.heads import diffusion_unet, flow_unet, mlp
from soe_jax.policies.heads.base import Head

_HEADS: dict[str, Callable[..., Head]] = {}


def register_head(name: str, factory: Callable[..., Head]) -> None:
  _HEADS[name] = factory


def head_names() -> list[str]:
  return sorted(_HEADS)


def make_head(name: str, action_dim: int, horizon: int, **kwargs) -> Head:
  if name not in _HEADS:
    raise ValueError(f"unknown head {name!r}; known heads: {', '.join(head_names())}")
  return _HEADS[name](action_dim=action_dim, horizon=horizon, **kwargs)


register_head("diffusion_unet", diffusion_unet.make)
register_head("flow_unet", flow_unet.make)
register_head("mlp", mlp.make)
