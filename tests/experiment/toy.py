"""A trivial pure-JAX task for the loop's logic, after brax's `envs/fast.py`: a point (the "grip site")
that must reach a goal, with the observation keys a policy reads (`observations.POLICY_OBS_KEYS`, the
goal as `object`), success in `metrics["success"]`, and its scripted demonstrator (head for the goal).
It imports neither MuJoCo nor brax, so a run on it is seconds of JAX.

`registered()` adds the task and its demonstrator as "toy" while inside; `get_config(presets)` is its
config (`toy_config.py`, a config file).
"""

from __future__ import annotations

import contextlib
import dataclasses

import jax
import jax.numpy as jnp
import ml_collections
import numpy as np
from flax import struct

from soe_jax import geometry
from soe_jax.envs import controller, observations
from soe_jax.envs import registry as env_registry
from soe_jax.experts import registry as expert_registry
from tests.experiment.toy_config import NAME, get_config  # noqa: F401 (toy.get_config: the config file's)

START = np.array([-0.1, 0.0, 1.0], np.float32)  # the point's start, +- START_NOISE
START_NOISE = 0.02
# The goal lies within GOAL_RANGE of START + GOAL_OFFSET in each direction, some 11 steps away; an
# episode succeeds within SUCCESS_RADIUS of it, so even a policy that has learnt little (heading for the
# goals' mean) succeeds from about half of the start states: rounds keep episodes and fit on them.
GOAL_OFFSET = np.array([0.36, 0.0, 0.0], np.float32)
GOAL_RANGE = 0.05
SUCCESS_RADIUS = 0.05
MAX_STEP = 0.03  # m per control step towards the commanded position
HAND_QUAT = np.array([0.0, 0.0, 0.0, 1.0], np.float32)  # xyzw: the hand never turns
TOP_DOWN = geometry.mat_to_rot6d(jnp.eye(3))  # the action's rotation (the point ignores it)


@struct.dataclass
class Point:
  """The simulator state: qpos = (point (3), goal (3)), qvel = the point's velocity (3), and the time."""

  qpos: jax.Array
  qvel: jax.Array
  time: jax.Array


@struct.dataclass
class State:
  """brax's `State`, as far as the loop reads it."""

  pipeline_state: Point
  obs: dict
  reward: jax.Array
  done: jax.Array
  metrics: dict = struct.field(default_factory=dict)
  info: dict = struct.field(default_factory=dict)


class Physics:
  """What the rollout engine and the demonstrations ask of a task's backend: the recorded simulator
  state [time, qpos, qvel] (robomimic's `states`), as float64 on the host, and the check after a call."""

  name = "toy"

  def sim_state(self, ps: Point) -> jax.Array:
    return jnp.concatenate([ps.time[..., None], ps.qpos, ps.qvel], -1)

  def sim_state_float64(self, recorded) -> np.ndarray:
    return np.asarray(recorded, np.float64)

  def check(self, ps: Point) -> None:
    """Nothing to check."""

  def where(self, done, reset: Point, state: Point) -> Point:
    return jax.tree.map(lambda r, s: jnp.where(done, r, s), reset, state)


class Toy:
  """Reach the goal: the action's first 3 numbers are the commanded position (`absolute` mode's
  10-number layout), which the point approaches by at most `MAX_STEP` per control step; the episode
  succeeds once it is within `SUCCESS_RADIUS` of the goal."""

  name = NAME
  bases = ((tuple(START), 0.0),)  # one robot
  object_dim = 3  # the goal's position
  object_layout = (("pos", 3),)
  image_cameras = ()
  # The demonstrator commands the goal: its range, widened by 2 cm (`experts.workspace.MARGIN`).
  workspace = (tuple(zip(*[(c - GOAL_RANGE - 0.02, c + GOAL_RANGE + 0.02) for c in (START + GOAL_OFFSET).tolist()])),)

  def __init__(self, config: ml_collections.ConfigDict | None = None):
    self.config = config if config is not None else self.default_config()
    if self.config.action_mode != "absolute":
      raise ValueError(f"the toy task takes absolute actions, not {self.config.action_mode!r}")
    self.action_mode = self.config.action_mode
    self.num_robots = len(self.bases)
    self.episode_length = int(self.config.episode_length)
    self.obs_mode = self.config.obs_mode
    self.physics = Physics()
    self.backend = self.physics.name

  @classmethod
  def default_config(cls) -> ml_collections.ConfigDict:
    return ml_collections.ConfigDict(dict(action_mode="absolute", episode_length=24, obs_mode="low_dim"))

  @property
  def action_size(self) -> int:
    return controller.action_size(self.action_mode) * self.num_robots

  @property
  def observation_size(self) -> int:
    return observations.policy_obs_size(self.object_dim, self.num_robots)

  @property
  def policy_obs_keys(self) -> tuple[str, ...]:
    return observations.policy_obs_keys(self.num_robots)

  @property
  def obs_min_span(self) -> np.ndarray:
    layout = observations.ROBOT_OBS_LAYOUT * self.num_robots + self.object_layout
    return np.concatenate([np.full(size, observations.MIN_SPAN[kind], np.float32) for kind, size in layout])

  def conform_quaternions(self, obs: dict) -> dict:
    """The hand never turns: observations come back as they are."""
    return {k: np.array(v) for k, v in obs.items()}

  def reset(self, rng: jax.Array) -> State:
    key_start, key_goal = jax.random.split(rng)
    start = START + jax.random.uniform(key_start, (3,), minval=-START_NOISE, maxval=START_NOISE)
    goal = START + GOAL_OFFSET + jax.random.uniform(key_goal, (3,), minval=-GOAL_RANGE, maxval=GOAL_RANGE)
    ps = Point(qpos=jnp.concatenate([start, goal]), qvel=jnp.zeros(3), time=jnp.zeros(()))
    obs, success = self._observe(ps, controller.gripper_targets(jnp.array(-1.0)))  # open
    zero = jnp.zeros(())
    return State(pipeline_state=ps, obs=obs, reward=zero, done=zero, metrics={"success": success}, info={"rng": rng})

  def step(self, state: State, action: jax.Array) -> State:
    ps = state.pipeline_state
    move = action[:3] - ps.qpos[:3]
    move = move * jnp.minimum(1.0, MAX_STEP / jnp.maximum(jnp.linalg.norm(move), 1e-9))
    ps = Point(qpos=ps.qpos.at[:3].add(move), qvel=move / controller.CONTROL_DT, time=ps.time + controller.CONTROL_DT)
    obs, success = self._observe(ps, controller.gripper_targets(action[9]))
    return state.replace(pipeline_state=ps, obs=obs, reward=success, done=success, metrics={"success": success})

  def _observe(self, ps: Point, fingers: jax.Array):
    point, goal = ps.qpos[:3], ps.qpos[3:]
    obs = dict(
      robot0_eef_pos=point,
      robot0_eef_quat=jnp.asarray(HAND_QUAT),
      robot0_gripper_qpos=fingers,
      object=goal,
      robot0_joint_pos=jnp.zeros(7),  # (the demonstrations record every robot's joints)
      robot0_eef_rot=jnp.eye(3).reshape(9),
    )
    return obs, (jnp.linalg.norm(point - goal) < SUCCESS_RADIUS).astype(jnp.float32)


@dataclasses.dataclass(frozen=True)
class Reach:
  """The toy's scripted demonstrator: command the goal, gripper open, every step (it arrives in some
  (|GOAL_OFFSET| - SUCCESS_RADIUS) / MAX_STEP = 11 steps, inside the smoke preset's 24)."""

  def init(self, obs: dict, key: jax.Array, resume: bool = False) -> jax.Array:
    return jnp.zeros(())

  def act(self, es: jax.Array, obs: dict):
    return jnp.concatenate([obs["object"], TOP_DOWN, jnp.array([-1.0])]), es


EXPERT = Reach()


@contextlib.contextmanager
def registered():
  """The toy task and its demonstrator registered as "toy" while inside; the registries have no
  removal, so the names are taken out here again after (the real tasks' lists stay as they were)."""
  env_registry.register_env(NAME, Toy)
  expert_registry.register_expert(NAME, lambda: EXPERT)
  try:
    yield
  finally:
    env_registry.TASKS._factories.pop(NAME)
    expert_registry.EXPERTS._factories.pop(NAME)
