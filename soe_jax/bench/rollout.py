"""Rollout throughput with the policy in the loop: a batch of environments, a freshly initialised
policy of the config's size, and one exploration strategy. The compiled decision program is timed
after its first (compiling) call; an untrained policy does not finish episodes, so every environment
does real work throughout. The strategy's settings are the config's when it names the same strategy
(`configs/lift.py:cpu,soe_steer`), its defaults otherwise. `soe_steer` steers along the first
`max_dims` (0: 4) latent dimensions with the scripted chooser at every decision, so its figure is the
cost of one steering decision."""

from __future__ import annotations

import dataclasses
import time

import jax
import ml_collections
import numpy as np

from soe_jax.envs import registry
from soe_jax.experiment import task
from soe_jax.explore import registry as strategy_registry
from soe_jax.explore import rollout
from soe_jax.policies import normalizer as normalizer_lib
from soe_jax.policies.agent import Agent


def run(config: ml_collections.ConfigDict, strategy: str, num_envs: int, decisions: int = 2, repeats: int = 3) -> dict:
  config = ml_collections.ConfigDict(config)
  env = registry.env_from_config(config.env)
  policy = task.policy(config)
  rng = np.random.default_rng(0)
  obs = rng.uniform(-0.3, 1.1, (256, policy.obs_dim))
  actions = rng.uniform(-1, 1, (256, policy.action_dim))
  agent = Agent(policy, policy.init(jax.random.key(0)), normalizer_lib.fit(obs, actions))
  name = strategy or config.explore.strategy.name
  settings = dict(config.explore.strategy.kwargs) if name == config.explore.strategy.name else {}
  if name == "soe_steer":
    settings["every"] = 1
  strat = strategy_registry.make_strategy(name, env, **settings)
  if name == "soe_steer":
    strat = dataclasses.replace(strat, dims=tuple(range(min(strat.max_dims or 4, policy.p_net.latent_dim))))
  keys = jax.random.split(jax.random.key(1), num_envs)
  fn = rollout.decisions_fn(env, strat, policy.n_action_steps, decisions)
  carry = rollout.initial_carry(env, policy.n_obs_steps, keys)
  t = time.perf_counter()
  carry, out = fn(carry, agent, jax.random.key(0))
  jax.block_until_ready(out)
  first = time.perf_counter() - t
  times = []
  for r in range(repeats):
    t = time.perf_counter()
    carry, out = fn(carry, agent, jax.random.key(r + 1))
    jax.block_until_ready(out)
    times.append(time.perf_counter() - t)
  per_call = float(np.median(times))
  steps = num_envs * decisions * policy.n_action_steps
  return dict(
    bench="rollout",
    task=env.name,
    backend=env.backend,
    strategy=name,
    num_envs=num_envs,
    head=config.policy.head.name,
    down_dims=list(config.policy.head.kwargs.get("down_dims", [])),
    steer_dims=len(strat.dims) if name == "soe_steer" else 0,
    proposals=strat.num_proposals if name == "soe_steer" else 0,
    env_steps_per_s=round(steps / per_call, 1),
    ms_per_chunk=round(1000 * per_call / decisions, 1),
    first_call_s=round(first, 1),
  )
