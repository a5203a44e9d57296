"""What a policy server does per connection, without the network: check an observation against the
policy's spec, keep the connection's observation history, sample a chunk and reply with its executed
actions. `server.py` puts it on a websocket.

A request is the robot's observation dict in raw units: every key of the spec (`data.spec.PolicySpec`:
low-dimensional vectors as float arrays of their shapes, camera images as (H, W, 3) uint8), plus
optionally `timestamp` (seconds, of the observation) and `episode_start` (true on an episode's first
observation; openpi's `reset()` sends nothing, so the robot says it here). Other keys are ignored.
The reply holds chunk-first arrays, as openpi's `ActionChunkBroker(policy, action_horizon=Ta)` slices:

  actions     (Ta, A) float32   chunk[To-1 : To-1+Ta] in the robot's frame (absolute poses)
  timestamps  (Ta,)   float64   when each action is due: the observation's timestamp + i / control_hz
  server_timing {"infer_ms": ...}  (added by the server)

The sampling key of request n of the connection's episode e is fold_in(fold_in(key(seed), e), n), so a
fixed observation and key give the chunk the policy gives in-process (`request_key`).
"""

from __future__ import annotations

import functools
import time

import jax
import numpy as np

from soe_jax.data.spec import PolicySpec
from soe_jax.policies import agent as agent_lib
from soe_jax.policies.agent import Agent

BOX_TOL = 1e-5  # relative to the box's size: the sampler's clip lands on its faces, in float32


class RequestError(ValueError):
  """The client's request is not what the spec asks for (one line for the error frame)."""


class PolicyError(RuntimeError):
  """The policy's chunk is not fit to send (not finite, or outside the action box)."""


def request_key(seed: int, episode: int, step: int) -> jax.Array:
  return jax.random.fold_in(jax.random.fold_in(jax.random.key(seed), episode), step)


@functools.lru_cache(maxsize=8)
def chunk_fn(policy):
  """The compiled (agent, history, key) -> chunk the server samples with (one per policy)."""
  return jax.jit(lambda agent, history, key: agent.chunk(history, key))


def policy_input(spec: PolicySpec, obs: dict):
  """A checked raw observation dict -> one policy observation (batch of 1): the low-dim vector (1, D)
  of the spec's keys in order, with {"lowdim", "images"} for an image policy."""
  if not isinstance(obs, dict):
    raise RequestError(f"a request is a dict of observations, got {type(obs).__name__}")
  missing = [k for k in spec.observations if k not in obs]
  if missing:
    raise RequestError(f"missing observation keys {missing}; the policy reads {list(spec.observations)}")
  parts, images = [], {}
  for key, info in spec.observations.items():
    value = obs[key]
    if not isinstance(value, (np.ndarray, np.generic, list, float, int)):
      raise RequestError(f"observation {key!r} is a {type(value).__name__}, not an array")
    value = np.asarray(value)
    shape = tuple(info["shape"])
    if info.get("image"):
      if value.dtype != np.uint8 or value.shape != shape:
        raise RequestError(f"image {key!r} must be uint8 of shape {list(shape)}, got {value.dtype} {list(value.shape)}")
      images[key] = value[None]
    else:
      if value.dtype.kind not in "fiu" or value.shape != shape:
        raise RequestError(
          f"observation {key!r} must be numbers of shape {list(shape)}, got {value.dtype} {list(value.shape)}"
        )
      if not np.all(np.isfinite(value)):
        raise RequestError(f"observation {key!r} is not finite: {value.tolist()}")
      parts.append(value.astype(np.float32).reshape(-1))
  vector = np.concatenate(parts)[None] if parts else np.zeros((1, 0), np.float32)
  return {"lowdim": vector, "images": images} if images else vector


class Session:
  """One connection's episode: its observation history and its requests' keys."""

  def __init__(self, agent: Agent, spec: PolicySpec, seed: int = 0):
    self.agent, self.spec, self.seed = agent, spec, int(seed)
    self.history = None
    self.episode, self.step = -1, 0
    self.bounds = spec.action_bounds()

  def infer(self, obs: dict) -> dict:
    """The reply to one observation (see the module's docstring); RequestError for a bad request,
    PolicyError for a chunk that must not be sent."""
    x = policy_input(self.spec, obs)
    scalar = lambda v: v.item() if isinstance(v, np.ndarray) and v.shape == () else v  # openpi packs 0-d arrays so
    start = scalar(obs.get("episode_start", False))
    if not isinstance(start, (bool, np.bool_)):
      raise RequestError(f"episode_start must be true or false, got {start!r}")
    stamp = scalar(obs.get("timestamp", time.time()))
    if not isinstance(stamp, (int, float, np.number)) or not np.isfinite(stamp):
      raise RequestError(f"timestamp must be a number of seconds, got {stamp!r}")
    if start or self.history is None:
      self.episode, self.step = self.episode + 1, 0
      self.history = agent_lib.initial_history(x, self.agent.policy.n_obs_steps)
    else:
      self.history = agent_lib.push_history(self.history, x)
    key = request_key(self.seed, self.episode, self.step)
    self.step += 1
    chunk = chunk_fn(self.agent.policy)(self.agent, self.history, key)
    actions = np.asarray(jax.device_get(self.agent.executed(chunk))[0], np.float32)
    self.check(actions)
    dt = 1.0 / self.spec.control_hz
    return {"actions": actions, "timestamps": float(stamp) + dt * np.arange(len(actions), dtype=np.float64)}

  def check(self, actions: np.ndarray) -> None:
    if not np.all(np.isfinite(actions)):
      raise PolicyError("the policy's chunk is not finite; nothing was sent")
    if self.bounds is not None:
      lo, hi = self.bounds
      tol = BOX_TOL * np.where(np.isfinite(hi - lo), hi - lo, 0.0)
      out = (actions < lo - tol) | (actions > hi + tol)
      if out.any():
        t, d = map(int, np.argwhere(out)[0])
        raise PolicyError(
          f"the policy's action {t} leaves the action box in dimension {d} ({actions[t, d]:.5f} not in "
          f"[{lo[d]:.5f}, {hi[d]:.5f}]); nothing was sent"
        )


def warm_up(agent: Agent, spec: PolicySpec) -> None:
  """Compile the chunk of one observation history (before a server listens)."""
  zeros = {k: np.zeros(v["shape"], np.uint8 if v.get("image") else np.float32) for k, v in spec.observations.items()}
  history = agent_lib.initial_history(policy_input(spec, zeros), agent.policy.n_obs_steps)
  jax.block_until_ready(chunk_fn(agent.policy)(agent, history, request_key(0, 0, 0)))


def metadata(spec: PolicySpec, agent: Agent) -> dict:
  """The frame sent on connect: the spec and the chunk's timing."""
  p = agent.policy
  return dict(
    server="soe_jax",
    protocol="openpi websocket + msgpack-numpy",
    spec=spec.to_dict(),
    n_obs_steps=p.n_obs_steps,
    horizon=p.horizon,
    action_horizon=p.n_action_steps,
    control_hz=spec.control_hz,
    request_keys=list(spec.observations) + ["timestamp (optional)", "episode_start (optional)"],
    reply_keys=["actions", "timestamps", "server_timing"],
  )
