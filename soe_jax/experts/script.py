"""A waypoint-script demonstrator in pure JAX (vmappable, jittable).

A task's expert is a list of phases. When a phase starts, its plan function reads the observation and
the episode's random parameters and returns a target: grip-site position, yaw of a top-down grasp
frame, gripper command, speed, and how long to hold. The commanded pose moves from where the previous
phase left it to the target along a minimum-jerk profile, so motion is smooth; the phase ends once
the end effector has arrived (or a timeout passes). A target may bend its path (`bend`: the control
point of a quadratic Bezier curve, as an offset from the straight path's midpoint), for an arced
approach; unbent, the path is the straight line. Per-episode randomness (speed, heights, offsets,
waiting times) and a small smooth (AR(1)) positional noise give human-like variety.

A phase may also wait for the scene (`ready`, read every step): a two-arm task runs one script per arm
(`BimanualExpert`), and an arm's phase that needs the other arm (a handover) waits until the
observation shows it has done its part.

An expert can also start mid-episode: `init(obs, key, resume=True)` asks the task's `resume(obs)` which
phase the scene is in (for example: holding the object, so carry on lifting) and plans from the
current end-effector pose. Steering's scripted chooser and the `expert` strategy use this, resuming at
every decision; so that this does not restart a minimum-jerk profile (which starts at rest) every few
steps, a resumed expert's first motion moves at its constant speed (from rest; the later phases are
minimum-jerk again).

The action is the 10-d absolute pose of the script's robot (`robot`, its `robot<k>_` observations):
position, rotation-6d of the top-down frame at the commanded yaw, gripper.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from typing import NamedTuple

import jax
import jax.numpy as jnp
from flax import struct

from soe_jax import geometry

TIMEOUT = 30  # steps a phase may wait beyond its schedule for the arm to arrive


class Target(NamedTuple):
  pos: jax.Array  # (3,) grip-site position
  yaw: jax.Array  # () yaw of the grasp frame's closing axis
  grip: jax.Array  # () -1 open .. +1 closed
  speed: jax.Array  # () m per control step along the path
  hold: jax.Array  # () int, steps to wait after arriving on schedule
  tol: jax.Array  # () m, arrival tolerance of the measured end effector
  bend: jax.Array  # (3,) m, the path's control point off the straight path's midpoint (0: straight)


@struct.dataclass
class ExpertState:
  phase: jax.Array
  t: jax.Array
  start_pos: jax.Array
  start_yaw: jax.Array
  target: Target
  duration: jax.Array
  cmd_pos: jax.Array
  cmd_yaw: jax.Array
  noise: jax.Array
  params: dict
  key: jax.Array
  linear: jax.Array  # () bool: the current motion moves at constant speed (a resumed expert's first)


def topdown_rot(yaw: jax.Array) -> jax.Array:
  """Grip-site rotation pointing the approach axis (z) down, closing axis (x) at `yaw`."""
  c, s = jnp.cos(yaw), jnp.sin(yaw)
  zero = jnp.zeros_like(c)
  x = jnp.stack([c, s, zero])
  y = jnp.stack([s, -c, zero])
  z = jnp.stack([zero, zero, -jnp.ones_like(c)])
  return jnp.stack([x, y, z], axis=1)


def site_yaw(obs: dict, robot: int = 0) -> jax.Array:
  r = obs[f"robot{robot}_eef_rot"].reshape(3, 3)
  return jnp.arctan2(r[1, 0], r[0, 0])


def quat_yaw_xyzw(q: jax.Array) -> jax.Array:
  x, y, z, w = q[0], q[1], q[2], q[3]
  return jnp.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


def nearest_equivalent(angle: jax.Array, reference: jax.Array, period: float) -> jax.Array:
  """The angle equal to `angle` modulo `period` that is closest to `reference`."""
  return reference + jnp.mod(angle - reference + period / 2, period) - period / 2


def min_jerk(tau: jax.Array) -> jax.Array:
  return tau**3 * (10 - 15 * tau + 6 * tau**2)


@dataclasses.dataclass(frozen=True)
class ScriptedExpert:
  """`plans[i](obs, params, cmd_pos, cmd_yaw) -> Target`; `sample_params(key) -> dict`;
  `resume(obs) -> phase index` to start from in the scene `obs` shows; `ready` (optional, one per
  phase): `ready[i](obs, params) -> bool`, phase i ends only once it holds; `robot`: whose arm."""

  plans: Sequence[Callable[..., Target]]
  sample_params: Callable[[jax.Array], dict]
  resume: Callable[[dict], jax.Array]
  ready: Sequence[Callable[[dict, dict], jax.Array]] | None = None
  robot: int = 0
  noise_std: float = 0.0004  # m, innovation of the AR(1) positional noise
  noise_decay: float = 0.9

  def init(self, obs: dict, key: jax.Array, resume: bool = False) -> ExpertState:
    """Start at the first phase, or with `resume` at the phase `self.resume(obs)` names."""
    key_params, key = jax.random.split(key)
    pos, yaw = obs[f"robot{self.robot}_eef_pos"], site_yaw(obs, self.robot)
    zero_t = Target(pos, yaw, jnp.array(-1.0), jnp.array(0.01), jnp.array(0), jnp.array(0.01), jnp.zeros(3))
    phase = jnp.asarray(self.resume(obs), jnp.int32) if resume else jnp.array(0)
    return ExpertState(
      phase=phase,
      t=jnp.array(0),
      start_pos=pos,
      start_yaw=yaw,
      target=zero_t,
      duration=jnp.array(1),
      cmd_pos=pos,
      cmd_yaw=yaw,
      noise=jnp.zeros(3),
      params=self.sample_params(key_params),
      key=key,
      linear=jnp.asarray(resume),
    )

  def act(self, es: ExpertState, obs: dict):
    """-> (action (10,), next ExpertState)."""
    last = len(self.plans) - 1
    starting = es.t == 0
    planned = jax.lax.switch(es.phase, list(self.plans), obs, es.params, es.cmd_pos, es.cmd_yaw)
    target = jax.tree.map(lambda new, old: jnp.where(starting, new, old), planned, es.target)
    start_pos = jnp.where(starting, es.cmd_pos, es.start_pos)
    start_yaw = jnp.where(starting, es.cmd_yaw, es.start_yaw)
    dist = (
      jnp.linalg.norm(target.pos - start_pos) + 0.05 * jnp.abs(target.yaw - start_yaw) + jnp.linalg.norm(target.bend)
    )
    duration = jnp.where(starting, jnp.maximum(2, jnp.ceil(dist / target.speed)).astype(jnp.int32), es.duration)
    tau = jnp.minimum((es.t + 1) / duration, 1.0)
    s = jnp.where(es.linear, tau, min_jerk(tau))
    cmd_pos = start_pos + (target.pos - start_pos) * s + 2 * s * (1 - s) * target.bend  # (the Bezier curve)
    cmd_yaw = start_yaw + (target.yaw - start_yaw) * s

    key, key_noise = jax.random.split(es.key)
    noise = self.noise_decay * es.noise + self.noise_std * jax.random.normal(key_noise, (3,))
    action = jnp.concatenate([cmd_pos + noise, geometry.mat_to_rot6d(topdown_rot(cmd_yaw)), target.grip[None]])

    elapsed = es.t + 1
    scheduled = elapsed >= duration + target.hold
    arrived = jnp.linalg.norm(obs[f"robot{self.robot}_eef_pos"] - target.pos) < target.tol
    ready = jax.lax.switch(es.phase, list(self.ready), obs, es.params) if self.ready else True
    advance = scheduled & (arrived | (elapsed >= duration + target.hold + TIMEOUT)) & ready & (es.phase < last)
    nxt = es.replace(
      phase=jnp.where(advance, es.phase + 1, es.phase),
      t=jnp.where(advance, 0, elapsed),
      start_pos=start_pos,
      start_yaw=start_yaw,
      target=target,
      duration=duration,
      cmd_pos=cmd_pos,
      cmd_yaw=cmd_yaw,
      noise=noise,
      key=key,
      linear=es.linear & ~advance,
    )
    return action, nxt


@dataclasses.dataclass(frozen=True)
class BimanualExpert:
  """One script per arm, robot0's first, stepped together: the same `init` / `act` as a
  `ScriptedExpert`, with the arms' actions concatenated (20 numbers) and a state per arm."""

  arms: tuple[ScriptedExpert, ...]

  def init(self, obs: dict, key: jax.Array, resume: bool = False) -> tuple[ExpertState, ...]:
    return tuple(arm.init(obs, k, resume) for arm, k in zip(self.arms, jax.random.split(key, len(self.arms))))

  def act(self, es: tuple[ExpertState, ...], obs: dict):
    """-> (action (10 * arms,), next states)."""
    actions, states = zip(*(arm.act(s, obs) for arm, s in zip(self.arms, es)))
    return jnp.concatenate(actions), tuple(states)


def always(obs: dict, params: dict) -> jax.Array:
  """A phase that waits for nothing in the scene."""
  return jnp.array(True)


def uniform(key, lo, hi, shape=()):
  return jax.random.uniform(key, shape, minval=lo, maxval=hi)


def target(pos, yaw, grip, speed, hold=0, tol=0.01, bend=(0.0, 0.0, 0.0)) -> Target:
  f = lambda v: jnp.asarray(v, jnp.float32)
  return Target(f(pos), f(yaw), f(grip), f(speed), jnp.asarray(hold, jnp.int32), f(tol), f(bend))


def arced(plan: Callable[..., Target], side: str, size: str, hover: str) -> Callable[..., Target]:
  """`plan` with its path arced and a hover at its end, by the episode's parameters named `side`,
  `size` and `hover` (a varied demonstrator's approach or carry)."""

  def styled(obs, p, cmd_pos, cmd_yaw):
    t = plan(obs, p, cmd_pos, cmd_yaw)
    return t._replace(hold=t.hold + p[hover], bend=arc(cmd_pos, t.pos, p[side], p[size]))

  return styled


def paced(plan: Callable[..., Target], speed: str) -> Callable[..., Target]:
  """`plan` at the episode's speed parameter `speed` (a varied demonstrator's descent)."""
  return lambda obs, p, cmd_pos, cmd_yaw: plan(obs, p, cmd_pos, cmd_yaw)._replace(speed=p[speed])


def arc(start: jax.Array, end: jax.Array, side: jax.Array, size: jax.Array) -> jax.Array:
  """The `bend` of a path from `start` to `end` arcing `size` metres sideways (in the horizontal plane,
  to the left of the direction of travel for `side` +1, to the right for -1, straight for 0)."""
  d = end[:2] - start[:2]
  left = jnp.stack([-d[1], d[0]]) / jnp.maximum(jnp.linalg.norm(d), 1e-6)
  return jnp.concatenate([side * size * left, jnp.zeros(1)])


def near_xy(a: jax.Array, b: jax.Array, radius: float) -> jax.Array:
  return jnp.linalg.norm(a[:2] - b[:2]) < radius


def gripping(obs: dict, grip_pos: jax.Array, half_width: float, z_tol: float = 0.02, robot: int = 0) -> jax.Array:
  """Robot `robot`'s fingers are closed on an object part of half-width `half_width` centred at `grip_pos`."""
  eef = obs[f"robot{robot}_eef_pos"]
  closed = obs[f"robot{robot}_gripper_qpos"][0] < half_width + 0.004
  return near_xy(eef, grip_pos, 0.015) & (jnp.abs(eef[2] - grip_pos[2]) < z_tol) & closed
