"""Exploration strategies by name (`explore.strategy.name` in configs, with its settings in
`explore.strategy.kwargs`). Adding one: a file with a `Strategy` dataclass (imitate `soe.py`) and a
line below. `expert` imports the simulator and is registered by where it is defined, so that code
reading the other strategies' settings (a robot's server) does not load it."""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING

from soe_jax.explore import dp, sime, soe, steer
from soe_jax.registry import Registry
from soe_jax.types import Strategy

if TYPE_CHECKING:
  from soe_jax.envs.manipulation import ManipulationEnv

STRATEGIES: Registry[type[Strategy]] = Registry("exploration strategy", "strategies")
register_strategy = STRATEGIES.register
strategy_names = STRATEGIES.names


def default_settings(name: str) -> dict:
  """Strategy `name`'s settings with their defaults (its dataclass fields marked as settings)."""
  cls = STRATEGIES.factory(name)
  return {f.name: f.default for f in dataclasses.fields(cls) if f.init and f.metadata.get("setting", True)}


def make_strategy(name: str, env: ManipulationEnv | None = None, **settings) -> Strategy:
  """Strategy `name` with `settings` (the rest at their defaults); `soe_steer` and `expert` follow the
  task's demonstrator and need the task's `env`."""
  check_settings(name, settings)
  return STRATEGIES.factory(name).create(env, **settings)


def steering_strategy(strategy_config, env: ManipulationEnv) -> steer.SoeSteer:
  """`soe_steer` for steering a run by hand or analysing its latent: with the run's own settings
  (`explore.strategy`) where `soe_steer` has them (all of a soe_steer run's, a soe run's alpha), its
  defaults otherwise."""
  known = default_settings("soe_steer")
  return make_strategy("soe_steer", env, **{k: v for k, v in strategy_config.kwargs.items() if k in known})


def check_settings(name: str, settings) -> None:
  """Refuse an unknown strategy, or settings it does not have, listing what it has."""
  known = default_settings(name)
  unknown = sorted(set(settings) - set(known))
  if unknown:
    raise ValueError(
      f"strategy {name!r} has no setting {', '.join(map(repr, unknown))}; its settings: {', '.join(known) or 'none'}"
    )


register_strategy("dp", dp.Dp)
register_strategy("sime", sime.Sime)
register_strategy("soe", soe.Soe)
register_strategy("soe_steer", steer.SoeSteer)
register_strategy("expert", "soe_jax.explore.expert:Expert")
