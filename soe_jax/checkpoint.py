"""Checkpoints with orbax: the whole `TrainState` (parameters, EMA, optimiser state, step, normaliser
statistics) plus the config as JSON, restorable into a ready-to-sample policy with one call.

  save(directory, state, config)
  agent = load(directory).agent                    # the acting policy
  actions = agent.act(obs_history, key)            # raw (B, To, D) in (`agent`), raw executed (B, Ta, A) out
"""

from __future__ import annotations

import dataclasses
import json
import os

import jax
import jax.numpy as jnp
import ml_collections
import orbax.checkpoint as ocp

from soe_jax import train_state
from soe_jax.envs import registry
from soe_jax.policies import normalizer as normalizer_lib
from soe_jax.policies.agent import Agent
from soe_jax.policies.policy import Policy, make_policy

STATE_DIR = "state"
CONFIG_FILE = "config.json"
FORMAT_FILE = "format.json"
# What a saved state means. 2: observations normalised without clipping, with per-dimension span
# floors, and quaternion inputs in the continuous sign convention (`envs/manipulation.py`).
FORMAT = 2


def policy_from_config(config: ml_collections.ConfigDict) -> Policy:
  """The policy a run's config describes, sized for its task, action mode and images."""
  return make_policy(
    config.policy,
    registry.observation_size(config.env.task),
    registry.action_size(config.env.task, config.env.action_mode),
    int(config.env.get("image_size", 84)),
  )


def abstract_state(config: ml_collections.ConfigDict, policy: Policy) -> train_state.TrainState:
  """The shapes and dtypes of a TrainState for `config`, without allocating it."""
  tx = train_state.make_optimizer(config.fit, config.fit.num_steps)

  def build():
    params = policy.init(jax.random.PRNGKey(0))
    obs, act = jnp.zeros(policy.obs_dim), jnp.zeros(policy.action_dim)
    norm = normalizer_lib.Normalizer(obs_scale=obs, obs_offset=obs, act_scale=act, act_offset=act)
    return train_state.create(params, tx, norm, ema=config.fit.ema)

  return jax.eval_shape(build)


def save(directory: str, state: train_state.TrainState, config: ml_collections.ConfigDict) -> None:
  """Write `state` and `config` under `directory` (replacing what was there)."""
  directory = os.path.abspath(directory)
  os.makedirs(directory, exist_ok=True)
  with ocp.StandardCheckpointer() as checkpointer:  # closed on exit: its writes finished, its threads gone
    checkpointer.save(os.path.join(directory, STATE_DIR), jax.device_get(state), force=True)
  with open(os.path.join(directory, FORMAT_FILE), "w") as f:
    json.dump({"format": FORMAT}, f)
  tmp = os.path.join(directory, CONFIG_FILE + ".tmp")
  with open(tmp, "w") as f:
    f.write(config.to_json(indent=2))
  os.replace(tmp, os.path.join(directory, CONFIG_FILE))  # last: a checkpoint with a config is complete


@dataclasses.dataclass(frozen=True)
class LoadedPolicy:
  policy: Policy
  state: train_state.TrainState
  config: ml_collections.ConfigDict

  @property
  def agent(self) -> Agent:
    """The acting policy (EMA weights and the normaliser): `agent.act(obs_history, key)`."""
    return Agent.from_state(self.policy, self.state)


def load(directory: str) -> LoadedPolicy:
  """Restore a checkpoint written by `save` into a ready-to-sample policy."""
  directory = os.path.abspath(directory)
  config_path = os.path.join(directory, CONFIG_FILE)
  if not os.path.exists(config_path):
    raise FileNotFoundError(f"no checkpoint at {directory!r}: {CONFIG_FILE} is missing")
  format_path = os.path.join(directory, FORMAT_FILE)
  found = json.load(open(format_path))["format"] if os.path.exists(format_path) else 1
  if found != FORMAT:
    raise ValueError(
      f"the checkpoint at {directory!r} has format {found}, this code reads format {FORMAT}: it was written "
      "before observations were normalised without clipping and with span floors, and before quaternion "
      "inputs changed sign convention, so its policy would misread every observation; fit it again"
    )
  with open(config_path) as f:
    config = ml_collections.ConfigDict(json.load(f))
  policy = policy_from_config(config)
  target = abstract_state(config, policy)
  with ocp.StandardCheckpointer() as checkpointer:
    state = checkpointer.restore(os.path.join(directory, STATE_DIR), target)
  return LoadedPolicy(policy, state, config)
