"""Checkpoints with orbax: the whole `TrainState` (parameters, EMA, optimiser state, step, normaliser
statistics), the config as JSON and the policy's spec (`spec.json`: what it reads and writes,
`data.spec`), restorable into a ready-to-sample policy with one call and without the task registry.

  save(directory, state, config, spec)
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

from soe_jax.data import spec as spec_lib
from soe_jax.data.spec import PolicySpec
from soe_jax.policies import normalizer as normalizer_lib
from soe_jax.policies.agent import Agent
from soe_jax.policies.policy import Policy, policy_from_spec
from soe_jax.runtime import atomic, faults
from soe_jax.train import train_state

STATE_DIR = "state"
CONFIG_FILE = "config.json"
FORMAT_FILE = "format.json"
# What a saved state means (part of a shared round 0's key). 2: observations normalised without
# clipping, with per-dimension span floors, and quaternion inputs in the continuous sign convention
# (`envs/manipulation.py`).
STATE_FORMAT = 2
# The checkpoint's files. 3: `spec.json` beside the state; 2: the same state without it (its spec is
# the task's, given by the caller).
FORMAT = 3


def abstract_state(config: ml_collections.ConfigDict, policy: Policy) -> train_state.TrainState:
  """The shapes and dtypes of a TrainState for `config`, without allocating it."""
  tx = train_state.make_optimizer(config.fit, config.fit.num_steps)

  def build():
    params = policy.init(jax.random.key(0))
    obs, act = jnp.zeros(policy.obs_dim), jnp.zeros(policy.action_dim)
    norm = normalizer_lib.Normalizer(obs_scale=obs, obs_offset=obs, act_scale=act, act_offset=act)
    return train_state.create(params, tx, norm, ema=config.fit.ema)

  return jax.eval_shape(build)


def save(directory: str, state: train_state.TrainState, config: ml_collections.ConfigDict, spec: PolicySpec) -> None:
  """Write `state`, `spec` and `config` under `directory`, replacing what was there: all of it into a
  temporary directory beside it, renamed into place once complete (the write site "checkpoint")."""
  directory = os.path.abspath(directory)
  os.makedirs(os.path.dirname(directory), exist_ok=True)
  with faults.site("checkpoint"), atomic.replacing(directory) as tmp:
    os.makedirs(tmp)
    with ocp.StandardCheckpointer() as checkpointer:  # closed on exit: its writes finished, its threads gone
      checkpointer.save(os.path.join(tmp, STATE_DIR), jax.device_get(state))
    with open(os.path.join(tmp, FORMAT_FILE), "w") as f:
      json.dump({"format": FORMAT}, f)
    spec_lib.save(tmp, spec)
    atomic.write_json(os.path.join(tmp, CONFIG_FILE), json.loads(config.to_json()))


@dataclasses.dataclass(frozen=True)
class LoadedPolicy:
  policy: Policy
  state: train_state.TrainState
  config: ml_collections.ConfigDict
  spec: PolicySpec

  @property
  def agent(self) -> Agent:
    """The acting policy (EMA weights and the normaliser): `agent.act(obs_history, key)`."""
    return Agent.from_state(self.policy, self.state)


def load(directory: str, spec: PolicySpec | None = None) -> LoadedPolicy:
  """Restore a checkpoint written by `save` into a ready-to-sample policy. `spec`: the task's, for a
  checkpoint written before checkpoints carried their own (format 2); the saved one wins."""
  directory = os.path.abspath(directory)
  config_path = os.path.join(directory, CONFIG_FILE)
  if not os.path.exists(config_path):
    raise FileNotFoundError(f"no checkpoint at {directory!r}: {CONFIG_FILE} is missing")
  format_path = os.path.join(directory, FORMAT_FILE)
  found = json.load(open(format_path))["format"] if os.path.exists(format_path) else 1
  if found not in (2, FORMAT):
    raise ValueError(
      f"the checkpoint at {directory!r} has format {found}, this code reads formats 2 and {FORMAT}: it was "
      "written before observations were normalised without clipping and with span floors, and before "
      "quaternion inputs changed sign convention, so its policy would misread every observation; fit it again"
    )
  spec = spec_lib.load(directory) or spec
  if spec is None:
    raise ValueError(
      f"the checkpoint at {directory!r} has no {spec_lib.SPEC_FILE} (format {found}, written before checkpoints "
      "carried what their policy reads and writes): load it with its task's spec, "
      "checkpoint.load(directory, spec=soe_jax.experiment.task.spec(config))"
    )
  with open(config_path) as f:
    config = ml_collections.ConfigDict(json.load(f))
  policy = policy_from_spec(config.policy, spec)
  target = abstract_state(config, policy)
  with ocp.StandardCheckpointer() as checkpointer:
    state = checkpointer.restore(os.path.join(directory, STATE_DIR), target)
  return LoadedPolicy(policy, state, config, spec)
