"""The acting policy: a policy's networks with its evaluation parameters and normaliser, in raw units.

Every path from raw observations to raw actions goes through here: normalise the observation history
(B, To, D), sample normalised actions (B, T, A), unnormalise them. `act` means the executed actions,
Diffusion Policy's chunk[To-1 : To-1+Ta] (B, Ta, A), which the rollout runs open loop; `chunk` is the
whole predicted chunk. The observation history holds the last To policy observations, the first one
repeated at reset: (B, To, D), or for an image policy {"lowdim": (B, To, D), "images": {key: (B, To,
H, W, 3) uint8}} (`observations.policy_input`). A policy whose poses are relative to the latest observed
one (`policy.frame`, `frames`) gets its observations converted before they are normalised and its
chunks converted back after they are unnormalised: here, raw means absolute.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from flax import struct

from soe_jax.policies.normalizer import Normalizer
from soe_jax.policies.policy import Policy


@struct.dataclass
class Agent:
  policy: Policy = struct.field(pytree_node=False)
  params: dict
  normalizer: Normalizer

  @classmethod
  def from_state(cls, policy: Policy, state) -> Agent:
    """From a `TrainState`: the EMA parameters (if any) and its normaliser."""
    return cls(policy=policy, params=state.eval_params, normalizer=state.normalizer)

  def executed(self, chunk: jax.Array) -> jax.Array:
    """The Ta actions of a predicted chunk (B, T, A) that run open loop: chunk[:, To-1 : To-1+Ta]."""
    start = self.policy.n_obs_steps - 1
    return chunk[:, start : start + self.policy.n_action_steps]

  def observe(self, obs_history):
    """Raw observation histories -> the policy's normalised input (in its frame)."""
    frame = self.policy.frame
    if frame is not None:
      if isinstance(obs_history, dict):
        obs_history = dict(obs_history, lowdim=frame.observe(obs_history["lowdim"]))
      else:
        obs_history = frame.observe(obs_history)
    return self.normalizer.normalize_obs(obs_history)

  def actions(self, actions: jax.Array, obs_history) -> jax.Array:
    """Normalised actions (B, T, A) sampled for `obs_history` -> raw absolute ones."""
    actions = self.normalizer.unnormalize_actions(actions)
    if self.policy.frame is not None:
      lowdim = obs_history["lowdim"] if isinstance(obs_history, dict) else obs_history
      actions = self.policy.frame.to_absolute(lowdim, actions)
    return actions

  def chunk(self, obs_history: jax.Array, key: jax.Array, cond_fn=None) -> jax.Array:
    """Raw (B, T, A) from the base path a = D(E(o)); `cond_fn` perturbs the conditioning while sampling."""
    return self.actions(self.policy.sample(self.params, self.observe(obs_history), key, cond_fn), obs_history)

  def act(self, obs_history: jax.Array, key: jax.Array, cond_fn=None) -> jax.Array:
    """Raw executed actions (B, Ta, A) from the base path."""
    return self.executed(self.chunk(obs_history, key, cond_fn))

  def explore_chunk(self, obs_history: jax.Array, key: jax.Array, alpha, noise_key=None) -> tuple[jax.Array, jax.Array]:
    """Raw (B, T, A) from the exploration path with z ~ N(mu, (alpha sigma)^2), and z (B, d); the
    latent's noise from `noise_key` if given (else from `key`)."""
    actions, z = self.policy.sample_explore(self.params, self.observe(obs_history), key, alpha, noise_key)
    return self.actions(actions, obs_history), z

  def latent(self, obs_history: jax.Array) -> tuple[jax.Array, jax.Array]:
    """mu, log_std (B, d) of the latent for raw observation histories (B, To, D)."""
    cond = self.policy.encode(self.params, self.observe(obs_history))
    return self.policy.latent(self.params, cond)

  def decode_chunk(self, z: jax.Array, key: jax.Array, obs_history) -> jax.Array:
    """Raw (B, T, A) decoded from latents z (B, d) through q_phi and the head, for the observation
    histories (B, To, ...) the latents are of (a relative policy's chunks are converted against them)."""
    actions, _ = self.policy.head.sample(self.params["head"], self.policy.decode_latent(self.params, z), key)
    return self.actions(actions, obs_history)


def initial_history(obs, n_obs_steps: int):
  """(B, ...) the first policy observations (each array of either form) -> (B, To, ...), the first one
  repeated."""
  return jax.tree.map(lambda x: jnp.repeat(x[:, None], n_obs_steps, axis=1), obs)


def push_history(history, obs):
  """Drop the oldest of (B, To, ...) and append (B, ...)."""
  return jax.tree.map(lambda h, x: jnp.concatenate([h[:, 1:], x[:, None]], axis=1), history, obs)


def lowdim_latest(obs_history) -> jax.Array:
  """(B, D): the latest low-dim observation of histories of either form (what the policy read)."""
  lowdim = obs_history["lowdim"] if isinstance(obs_history, dict) else obs_history
  return lowdim[:, -1]


def batch_size(obs_history) -> int:
  """B of an observation history of either form."""
  return jax.tree.leaves(obs_history)[0].shape[0]
