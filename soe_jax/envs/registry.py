"""Tasks by name. `make_env("square")` builds one; unknown names list the known ones."""

from __future__ import annotations

import ml_collections

from soe_jax.envs import can, controller, lift, manipulation, square, transport
from soe_jax.registry import Registry

TASKS: Registry[manipulation.ManipulationEnv] = Registry("task")
register_env = TASKS.register
env_names = TASKS.names


def num_robots(name: str) -> int:
  """How many arms task `name` has (2 for transport, 1 for the others)."""
  return len(TASKS.factory(name).bases)


def observation_size(name: str) -> int:
  """The policy's observation size for task `name` (19 for lift, 23 for can and square, 59 for transport)."""
  return manipulation.policy_obs_size(TASKS.factory(name).object_dim, num_robots(name))


def action_size(name: str, action_mode: str) -> int:
  """The action size of task `name` in `action_mode`: 10 (absolute) or 7 (delta) per robot."""
  return controller.action_size(action_mode) * num_robots(name)


def image_keys(name: str) -> tuple[str, ...]:
  """The camera images task `name` draws with obs_mode="image" (robomimic's keys)."""
  return tuple(f"{c}_image" for c in TASKS.factory(name).image_cameras)


def make_env(name: str, config: ml_collections.ConfigDict | None = None, **overrides) -> manipulation.ManipulationEnv:
  """Build task `name`; `overrides` replace fields of its default config (e.g. backend="mjx")."""
  factory = TASKS.factory(name)
  config = ml_collections.ConfigDict(config if config is not None else factory.default_config())
  config.update(overrides)
  return factory(config)


def env_from_config(env_config: ml_collections.ConfigDict) -> manipulation.ManipulationEnv:
  """The task a run's `config.env` names (task, backend, action_mode, episode_length, ...)."""
  return make_env(env_config.task, **{k: v for k, v in env_config.items() if k != "task"})


register_env("lift", lift.Lift)
register_env("can", can.Can)
register_env("square", square.Square)
register_env("transport", transport.Transport)
