"""The task a run's config names: its environment (built once per process), and the spec and policy
a policy for it has (`data.spec.PolicySpec`: what it reads and writes)."""

from __future__ import annotations

import functools
import json

import ml_collections

from soe_jax.data.spec import PolicySpec
from soe_jax.envs import registry as env_registry
from soe_jax.policies import registry as policy_registry
from soe_jax.policies.policy import Policy, policy_from_spec


@functools.lru_cache(maxsize=8)
def _env(env_json: str):
  return env_registry.env_from_config(ml_collections.ConfigDict(json.loads(env_json)))


def env(config: ml_collections.ConfigDict):
  """The task `config.env` describes; built once per process for the same settings, so that runs
  beside each other share its compiled programs."""
  return _env(config.env.to_json())


def spec(config: ml_collections.ConfigDict) -> PolicySpec:
  """What a policy for `config`'s task reads (its low-dim keys; an image encoder's cameras) and writes."""
  encoder = config.policy.encoder
  cameras = ()
  if encoder.name == "image":
    cameras = tuple(policy_registry.make_encoder(encoder.name, **encoder.get("kwargs", {})).cameras)
  size = int(config.env.get("image_size", 84))
  spec = env_registry.task_spec(config.env.task, config.env.action_mode, cameras, size)
  if not config.env.get("object_vector", True):
    del spec["observations"]["object"]  # (an image policy sees the objects in its cameras)
  return PolicySpec.from_dict(spec)


@functools.lru_cache(maxsize=8)
def _policy(config_json: str) -> Policy:
  config = ml_collections.ConfigDict(json.loads(config_json))
  return policy_from_spec(config.policy, spec(config))


def policy(config: ml_collections.ConfigDict) -> Policy:
  """The policy `config` describes, sized for its task; one object per process for the same settings."""
  return _policy(json.dumps({k: json.loads(config.to_json())[k] for k in ("env", "policy")}))
