"""Tasks by name. `make_env("square")` builds one; unknown names list the known ones."""

from __future__ import annotations

from collections.abc import Callable

import ml_collections

from soe_jax.envs import can, lift, manipulation, square

_ENVS: dict[str, Callable[..., manipulation.ManipulationEnv]] = {}


def register_env(name: str, factory: Callable[..., manipulation.ManipulationEnv]) -> None:
  _ENVS[name] = factory


def env_names() -> list[str]:
  return sorted(_ENVS)


def _factory(name: str):
  if name not in _ENVS:
    raise ValueError(f"unknown task {name!r}; known tasks: {', '.join(env_names())}")
  return _ENVS[name]


def observation_size(name: str) -> int:
  """The policy's observation size for task `name` (19 for lift, 23 for can and square)."""
  return 9 + _factory(name).object_dim


def default_config(name: str) -> ml_collections.ConfigDict:
  return _factory(name).default_config()


def make_env(name: str, config: ml_collections.ConfigDict | None = None, **overrides) -> manipulation.ManipulationEnv:
  """Build task `name`; `overrides` replace fields of its default config (e.g. backend="mjx")."""
  factory = _factory(name)
  config = ml_collections.ConfigDict(config if config is not None else factory.default_config())
  config.update(overrides)
  return factory(config)


register_env("lift", lift.Lift)
register_env("can", can.Can)
register_env("square", square.Square)


def env_from_config(env_config: ml_collections.ConfigDict) -> manipulation.ManipulationEnv:
  """The task a run's `config.env` names (task, backend, action_mode, horizon, ...)."""
  fields = {k: v for k, v in env_config.items() if k != "task"}
  return make_env(env_config.task, **fields)
