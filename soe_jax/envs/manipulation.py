"""The shared manipulation environment of one or two Panda arms: a brax `Env` over either physics backend.

A task subclasses `ManipulationEnv` and supplies its robots' bases (`bases`), its scene
(`_scene_mjcf`), its start-state distribution (`_sample_objects`), its `object` observation
(`_object_obs`) and its success check (`_success`). Everything here is pure JAX; only the substep
loop differs between backends.

Robot k's joint positions are qpos[9k : 9k + 9] (7 arm joints, 2 finger slides), the objects' free
joints follow; its action is the k-th block of 10 (or 7) numbers, robot0 first.

Observations (`state.obs`, a dict with robomimic's key names), per robot k:
  robot<k>_eef_pos (3)       grip-site position, world frame
  robot<k>_eef_quat (4)      right_hand body orientation, xyzw
  robot<k>_gripper_qpos (2)  finger slide positions (open ~ (0.04, -0.04))
then object (Lift 10, Can 14, Square 14, Transport 41), and extras for experts and metrics:
robot<k>_joint_pos (7), robot<k>_eef_rot (9, grip-site rotation matrix, row-major). The policy sees
`policy_obs_keys(num_robots)` concatenated in that order (`POLICY_OBS_KEYS` for one robot; those and the
other pure-JAX readers of observations live in `observations`, free of MuJoCo, and are re-exported here). With
`obs_mode="image"` the observations also hold robomimic's camera images, uint8 (size, size, 3), rows
top-down, drawn after every control step (and at reset) from the joint positions on the host,
reached through `jax.pure_callback` on either backend, by a pool of OpenGL renderer processes
(`render.pool`) or MuJoCo Warp's batch ray tracer (`env.renderer`, `render.choice`); the single-arm
tasks' cameras (`CAMERAS`; a task may name others, `image_cameras`):
  agentview_image            the fixed camera facing the robot (robosuite's `agentview` pose)
  robot0_eye_in_hand_image   the wrist camera on the hand, looking out between the fingers

Quaternion inputs are continuous along every motion the tasks make (a quaternion and its negative are
the same rotation, so each quantity needs a sign convention):
- the hand's (`robot0_eef_quat`): the hemisphere of the hand's orientation at the arm's initial pose
  (`hand_reference`); the tasks turn the top-down hand far less than the 180 degrees that would reach
  the hemisphere's boundary (robomimic's w >= 0 puts that boundary at the top-down hand itself);
- an object's world orientation (in `object`): MuJoCo's own quaternion, whose sign the integrator
  carries continuously, drawn with w >= 0 at reset;
- an object's orientation in the eef frame (in `object`): conj(hand) * object of the two above, so it
  is continuous whenever they are.
`conform_quaternions` applies the same convention to observations recorded elsewhere.
"""

from __future__ import annotations

from soe_jax.envs import mjx_import  # noqa: F401 (first: MJX quietly, before brax imports it)

# isort: split
import time
from typing import NamedTuple

import jax
import jax.numpy as jnp
import ml_collections
import mujoco
import numpy as np
from brax.envs.base import Env, State

from soe_jax import geometry
from soe_jax.envs import backends, controller, panda, physics, rotations
from soe_jax.envs.observations import (
  MIN_SPAN,
  OBS_MODES,
  ROBOT_OBS_LAYOUT,
  policy_obs_keys,
  policy_obs_size,
)
from soe_jax.render import choice as render_choice

PHYSICS_DT = 0.002
AGENTVIEW = dict(pos="0.5 0 1.35", quat="0.653 0.271 0.271 0.653")
CAMERAS = ("agentview", panda.EYE_IN_HAND)  # image observation `<camera>_image` for each
IMAGE_KEYS = tuple(f"{c}_image" for c in CAMERAS)


def base_config() -> ml_collections.ConfigDict:
  """Fields every task shares; task modules extend it in their `default_config()`."""
  return ml_collections.ConfigDict(
    dict(
      backend="auto",  # auto | mujoco | mjx
      mjx_impl="auto",  # MJX's implementation: auto (warp on a CUDA GPU with warp-lang) | jax | warp
      mjx_max_batch=8192,  # the most environments stepped together on MJX-Warp (sizes its contacts)
      mjx_settings="",  # MJX's solver options: "" the task's, engine, or iterations=10,ls_iterations=8,cone=pyramidal
      action_mode="absolute",  # absolute (10-d) | delta (7-d)
      nsubsteps=25,  # physics substeps per 20 Hz control step
      episode_length=400,  # control steps: robomimic's evaluation horizon for lift / can / square
      obs_mode="low_dim",  # low_dim | image (adds the cameras' images to the observations)
      image_size=84,  # the images' height and width in pixels (robomimic's 84)
      renderer="auto",  # auto (warp on a CUDA GPU with warp-lang) | gl | warp (`render.choice`)
    )
  )


class Arm(NamedTuple):
  """What a task's `object` observation may read of one robot."""

  eef_pos: jax.Array  # (3,) grip site, world frame
  hand_rot: jax.Array  # (3, 3) right_hand body orientation
  hand_quat: jax.Array  # (4,) wxyz, in the hand's hemisphere


class ManipulationEnv(Env):
  """Panda arms + task scene, 20 Hz absolute end-effector pose control, sparse success reward."""

  name: str = ""
  # Each robot's base: ((x, y, z), yaw about world z), robot0 first.
  bases: tuple = (((-0.56, 0.0, 0.912), 0.0),)
  object_dim: int = 0
  # (kind, size) of the `object` vector's parts: pos, quat (world frame), rel_quat (in the eef frame).
  object_layout: tuple = ()
  # Each robot's workspace box ((lo x, y, z), (hi x, y, z)), robot0 first: the positions its scripted
  # demonstrator commands, widened (`experts.workspace`); the policy's actions are normalised over it.
  workspace: tuple | None = None
  agentview: dict = AGENTVIEW
  image_cameras: tuple = CAMERAS  # the cameras drawn with obs_mode="image", each `<camera>_image`
  # The accelerator scene: MJX's own solver options (MuJoCo Playground's Panda tasks use 5 / 8 and
  # pyramidal cones; the C engine keeps the scene's 100 / 50, elliptic), and MuJoCo Warp's buffers
  # per environment, sized at least 1.5x the most any demonstration state uses (`bench mjx`, a test).
  mjx_settings: dict = {"iterations": 10, "ls_iterations": 8, "cone": "pyramidal"}
  mjx_contacts: int = 32
  mjx_constraints: int = 256

  def __init__(self, config: ml_collections.ConfigDict | None = None):
    self.config = config if config is not None else self.default_config()
    self.action_mode = self.config.action_mode
    self.num_robots = len(self.bases)
    self._action_size = controller.action_size(self.action_mode) * self.num_robots
    self.mj_model = mujoco.MjModel.from_xml_string(self.mjcf())
    self.kins = tuple(panda.Kinematics(pos, yaw) for pos, yaw in self.bases)
    self.kin = self.kins[0]
    # wxyz, the hemispheres of each `robot<k>_eef_quat` (module docstring).
    self.hand_references = tuple(
      np.asarray(geometry.mat_to_quat_wxyz(kin.forward(jnp.asarray(panda.INIT_QPOS))["hand_rot"])) for kin in self.kins
    )
    self.hand_reference = self.hand_references[0]
    self.physics = physics.make_backend(
      self.config.backend,
      self.mj_model,
      self.config.nsubsteps,
      mjx_options=dict(
        impl=self.config.mjx_impl,
        settings=backends.parse_settings(self.config.mjx_settings, self.mjx_settings),
        contacts=self.mjx_contacts,
        constraints=self.mjx_constraints,
        max_batch=self.config.mjx_max_batch,
      ),
    )
    self.episode_length = int(self.config.episode_length)
    if self.config.obs_mode not in OBS_MODES:
      raise ValueError(
        f"unknown observation mode {self.config.obs_mode!r}; known observation modes: {', '.join(OBS_MODES)}"
      )
    self.obs_mode = self.config.obs_mode
    self.image_size = int(self.config.image_size)
    self.cameras = tuple(self.image_cameras) if self.obs_mode == "image" else ()
    self.image_keys = tuple(f"{c}_image" for c in self.cameras)
    # Started on the first image; `render_seconds` is the time spent drawing, for benchmarks.
    self.renderer = (
      render_choice.make(self.config.renderer, self.mj_model, self.cameras, self.image_size) if self.cameras else None
    )
    self.render_seconds = 0.0

  @classmethod
  def default_config(cls) -> ml_collections.ConfigDict:
    return base_config()

  # -- task hooks -----------------------------------------------------------------------------
  def _scene_mjcf(self) -> str:
    raise NotImplementedError

  def _assets_mjcf(self) -> str:
    """Meshes the scene uses (none by default)."""
    return ""

  def _sample_objects(self, key: jax.Array) -> jax.Array:
    """Object qpos (free joints) at reset, (nq - 9,)."""
    raise NotImplementedError

  def _object_obs(self, qpos: jax.Array, arms: tuple[Arm, ...]) -> jax.Array:
    """The task's `object` vector, laid out as `object_layout` says; `arms` are the robots', robot0 first."""
    raise NotImplementedError

  def _success(self, qpos: jax.Array, eef_pos: jax.Array) -> jax.Array:
    """Success at joint positions `qpos`, robot0's grip site at `eef_pos`."""
    raise NotImplementedError

  # -- model ----------------------------------------------------------------------------------
  def mjcf(self) -> str:
    cam = self.agentview
    return f"""<mujoco model="{self.name}">
  <compiler angle="radian" autolimits="true"/>
  <option timestep="{PHYSICS_DT}" integrator="implicitfast" cone="elliptic" impratio="20"/>
  <visual>
    <global offwidth="640" offheight="480"/><quality shadowsize="0"/>
    <headlight ambient="0.25 0.25 0.25" diffuse="0.3 0.3 0.3" specular="0 0 0"/>
  </visual>
  <asset>{self._assets_mjcf()}</asset>
  <worldbody>
    <light pos="0 0 3" dir="0 0 -1" directional="true" diffuse="0.4 0.4 0.4" specular="0.05 0.05 0.05"/>
    <light pos="1.5 1 2" dir="-0.6 -0.4 -0.7" directional="true" diffuse="0.2 0.2 0.2" specular="0 0 0"/>
    <geom name="floor" type="plane" size="3 3 0.1" {panda.FIXTURE_COLLISION} rgba="0.6 0.6 0.6 1"/>
    <camera name="agentview" {" ".join(f'{k}="{v}"' for k, v in cam.items())} fovy="45"/>
    {"".join(panda.robot_mjcf(pos, yaw, k) for k, (pos, yaw) in enumerate(self.bases))}
    {self._scene_mjcf()}
  </worldbody>
  <contact>{"".join(f'<exclude body1="{p}finger1" body2="{p}finger2"/>' for p in map(panda.prefix, range(len(self.bases))))}</contact>
  <actuator>{"".join(panda.robot_actuators_mjcf(k) for k in range(len(self.bases)))}</actuator>
</mujoco>"""

  @property
  def observation_size(self) -> int:
    return policy_obs_size(self.object_dim, self.num_robots)

  @property
  def policy_obs_keys(self) -> tuple[str, ...]:
    return policy_obs_keys(self.num_robots)

  @property
  def obs_layout(self) -> tuple:
    """(kind, size) of every part of the policy observation, in order."""
    return ROBOT_OBS_LAYOUT * self.num_robots + tuple(self.object_layout)

  @property
  def obs_min_span(self) -> np.ndarray:
    """(D,) the normaliser's smallest span per policy-observation dimension (`MIN_SPAN`)."""
    return np.concatenate([np.full(size, MIN_SPAN[kind], np.float32) for kind, size in self.obs_layout])

  def conform_quaternions(self, obs: dict) -> dict:
    """One episode's observations {key: (T, .)}, recorded with any quaternion signs, in this task's
    convention (module docstring); observations made here come back unchanged."""
    out = {k: np.array(v) for k, v in obs.items()}
    for k, reference in enumerate(self.hand_references):
      conformed = geometry.same_hemisphere(_wxyz(out[f"robot{k}_eef_quat"]), reference)
      out[f"robot{k}_eef_quat"] = np.asarray(rotations.wxyz_to_xyzw(conformed))
    hand = _wxyz(out["robot0_eef_quat"])  # the eef frame of `rel_quat` parts
    start, world = 0, None
    for kind, size in self.object_layout:
      part = slice(start, start + size)
      if kind == "quat":  # continuous along the episode from w >= 0 at its start
        q = np.asarray(_wxyz(out["object"][:, part]))
        for t in range(len(q)):
          q[t] = geometry.same_hemisphere(q[t], q[t - 1] if t else np.array([1.0, 0, 0, 0]))
        world = q
        out["object"][:, part] = np.asarray(rotations.wxyz_to_xyzw(q))
      elif kind == "rel_quat":  # conj(hand) * object
        expected = rotations.quat_mul_wxyz(rotations.quat_conj_wxyz(hand), world)
        out["object"][:, part] = np.asarray(
          rotations.wxyz_to_xyzw(geometry.same_hemisphere(_wxyz(out["object"][:, part]), expected))
        )
      start += size
    return out

  @property
  def action_size(self) -> int:
    return self._action_size

  @property
  def backend(self) -> str:
    """The physics backend actually used: `mujoco` or `mjx`."""
    return self.physics.name

  # -- brax Env -------------------------------------------------------------------------------
  def sample_qpos(self, rng: jax.Array) -> jax.Array:
    """The start state's joint positions (nq,), a pure function of the key."""
    key_arm, key_obj = jax.random.split(rng)
    arms = jnp.asarray(panda.INIT_QPOS) + panda.INIT_NOISE * jax.random.normal(key_arm, (self.num_robots, 7))
    fingers = jnp.broadcast_to(jnp.array([panda.FINGER_INIT, -panda.FINGER_INIT]), (self.num_robots, 2))
    robots = jnp.concatenate([arms, fingers], 1).reshape(-1)
    return jnp.concatenate([robots, self._sample_objects(key_obj)]).astype(jnp.float32)

  def reset(self, rng: jax.Array) -> State:
    qpos = self.sample_qpos(rng)
    ps = self.physics.init(qpos, jnp.zeros(self.mj_model.nv, jnp.float32))
    obs, success = self._observe(ps)
    zero = jnp.zeros(())
    return State(pipeline_state=ps, obs=obs, reward=zero, done=zero, metrics={"success": success}, info={"rng": rng})

  def step(self, state: State, action: jax.Array) -> State:
    if action.shape != (self.action_size,):
      raise ValueError(
        f"{self.name}: expected an action of shape ({self.action_size},) for action mode "
        f"{self.action_mode!r}, got {tuple(action.shape)}"
      )
    ps = self.physics.step(state.pipeline_state, self.controls(action, state.pipeline_state.qpos))
    obs, success = self._observe(ps)
    reward = self._get_reward(success)
    return state.replace(pipeline_state=ps, obs=obs, reward=reward, done=success, metrics={"success": success})

  def controls(self, action: jax.Array, qpos: jax.Array) -> jax.Array:
    """The servos' targets (9 per robot) for `action` (its k-th block robot k's) at joint positions `qpos`."""
    blocks = jnp.split(action, self.num_robots)
    return jnp.concatenate(
      [
        controller.joint_controls(kin, self.action_mode, a, qpos[9 * k : 9 * k + 7])
        for k, (kin, a) in enumerate(zip(self.kins, blocks))
      ]
    )

  def _get_reward(self, success: jax.Array) -> jax.Array:
    """Sparse, as robomimic evaluates: 1 on success."""
    return success

  def _observe(self, ps: physics.PhysicsState):
    qpos = ps.qpos
    obs, extras, arms = {}, {}, []
    for k, (kin, reference) in enumerate(zip(self.kins, self.hand_references)):
      q = qpos[9 * k : 9 * k + 9]
      fk = kin.forward(q[:7])
      hand_quat = geometry.mat_to_quat_wxyz(fk["hand_rot"], reference)
      obs[f"robot{k}_eef_pos"] = fk["site_pos"]
      obs[f"robot{k}_eef_quat"] = rotations.wxyz_to_xyzw(hand_quat)
      obs[f"robot{k}_gripper_qpos"] = q[7:9]
      extras[f"robot{k}_joint_pos"] = q[:7]
      extras[f"robot{k}_eef_rot"] = fk["site_rot"].reshape(9)
      arms.append(Arm(fk["site_pos"], fk["hand_rot"], hand_quat))
    obs = {**obs, "object": self._object_obs(qpos, tuple(arms)), **extras}
    if self.cameras:
      obs.update(self._images(qpos))
    return obs, self._success(qpos, arms[0].eef_pos).astype(jnp.float32)

  def _images(self, qpos: jax.Array) -> dict:
    """{`<camera>_image`: (..., size, size, 3) uint8} at joint positions `qpos` (..., nq), drawn on the host."""
    shape = jax.ShapeDtypeStruct(qpos.shape[:-1] + (self.image_size, self.image_size, 3), jnp.uint8)
    return jax.pure_callback(self.draw, {k: shape for k in self.image_keys}, qpos, vmap_method="broadcast_all")

  def draw(self, qpos) -> dict:
    """The cameras' images at joint positions `qpos` (..., nq) on the host: {`<camera>_image`: (...,
    size, size, 3) uint8 numpy}, as the observations hold them (e.g. an episode's, from its states)."""
    if self.renderer is None:
      raise ValueError(f"the {self.name} task was made with obs_mode={self.obs_mode!r}: it has no cameras to draw")
    t0 = time.perf_counter()
    qpos = np.asarray(qpos)
    images = self.renderer.render(qpos.reshape(-1, qpos.shape[-1]))
    batch = qpos.shape[:-1] + (self.image_size, self.image_size, 3)
    out = {f"{c}_image": images[c].reshape(batch) for c in self.cameras}
    self.render_seconds += time.perf_counter() - t0
    return out


# -- helpers shared by the task modules ---------------------------------------------------------
def free_body_pose(qpos: jax.Array, start: int):
  """(pos (3,), quat wxyz (4,)) of a free joint whose qpos starts at `start`."""
  return qpos[start : start + 3], qpos[start + 3 : start + 7]


def pose_in_eef(obj_pos, obj_quat_wxyz, eef_pos, hand_rot, hand_quat_wxyz):
  """Object pose in the eef frame (eef position, right_hand orientation), robosuite's obj_to_eef:
  (position (3,), xyzw quaternion conj(hand) * object (4,), continuous when both factors are)."""
  rel_pos = hand_rot.T @ (obj_pos - eef_pos)
  rel_quat = rotations.quat_mul_wxyz(rotations.quat_conj_wxyz(hand_quat_wxyz), obj_quat_wxyz)
  return rel_pos, rotations.wxyz_to_xyzw(rel_quat)


def yaw_free_qpos(pos, yaw) -> jax.Array:
  """Free-joint qpos (7,) for a body at `pos`, rotated by `yaw` about world z, its quaternion with
  w >= 0 (the object-orientation convention at reset; the same physical state for either sign)."""
  q = geometry.same_hemisphere(rotations.yaw_quat_wxyz(yaw), jnp.array([1.0, 0.0, 0.0, 0.0]))
  return jnp.concatenate([jnp.asarray(pos, jnp.float32), q])


def _wxyz(q_xyzw):
  return np.concatenate([q_xyzw[..., 3:], q_xyzw[..., :3]], -1)


def prism_mesh(name: str, radius: float, half_height: float, sides: int = 16) -> str:
  """A convex regular prism standing in for a cylinder. MJX (3.17) collides cylinders with planes,
  spheres, capsules and cylinders only; a convex mesh collides with boxes and meshes on both backends.
  The vertices lie on the cylinder's circle."""
  angles = np.arange(sides) * 2 * np.pi / sides
  ring = np.stack([radius * np.cos(angles), radius * np.sin(angles)], 1)
  verts = np.concatenate([np.concatenate([ring, np.full((sides, 1), z)], 1) for z in (-half_height, half_height)])
  return f'<mesh name="{name}" vertex="{np_fmt(verts)}"/>'


def np_fmt(v) -> str:
  return " ".join(f"{float(x):.6g}" for x in np.ravel(v))
