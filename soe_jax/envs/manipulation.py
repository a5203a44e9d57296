"""The shared single-arm manipulation environment: a brax `Env` over either physics backend.

A task subclasses `ManipulationEnv` and supplies its scene (`_scene_mjcf`), its start-state
distribution (`_sample_objects`), its `object` observation (`_object_obs`) and its success check
(`_success`). Everything here is pure JAX; only the substep loop differs between backends.

Observations (`state.obs`, a dict with robomimic's key names):
  robot0_eef_pos (3)       grip-site position, world frame
  robot0_eef_quat (4)      right_hand body orientation, xyzw
  robot0_gripper_qpos (2)  finger slide positions (open ~ (0.04, -0.04))
  object (Lift 10, Can 14, Square 14)
and extras for experts and metrics: robot0_joint_pos (7), robot0_eef_rot (9, grip-site rotation
matrix, row-major). The policy sees `POLICY_OBS_KEYS` concatenated in that order. With
`obs_mode="image"` the observations also hold robomimic's camera images, uint8 (size, size, 3), rows
top-down, drawn after every control step (and at reset) from the joint positions by a pool of
renderer processes on the host (`render.pool`), reached through `jax.pure_callback` on either
backend:
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

import time

import jax
import jax.numpy as jnp
import ml_collections
import mujoco
import numpy as np
from brax.envs.base import Env, State

from soe_jax.envs import controller, panda, physics, rotations
from soe_jax.render import pool

POLICY_OBS_KEYS = ("robot0_eef_pos", "robot0_eef_quat", "robot0_gripper_qpos", "object")
# Sizes of the policy's observation keys; `object` is the task's own (`ManipulationEnv.object_dim`).
ROBOT_OBS_SIZES = {"robot0_eef_pos": 3, "robot0_eef_quat": 4, "robot0_gripper_qpos": 2}
# What each policy-observation number is: (kind, size) in order; tasks give their `object_layout`.
ROBOT_OBS_LAYOUT = (("pos", 3), ("hand_quat", 4), ("finger", 2))
# The smallest span the normaliser maps to [-1, 1] per kind, from the quantity's physical range, so no
# dimension's gain exceeds 2 / span: positions 0.08 m (a tenth of the 0.8 m table, the workspace;
# gain <= 25 per m), fingers their 0.04 m travel (<= 50 per m), unit-quaternion components a quarter
# of their [-1, 1] range (<= 4).
MIN_SPAN = {"pos": 0.08, "finger": 0.04, "hand_quat": 0.5, "quat": 0.5, "rel_quat": 0.5}
CONTROL_DT = 0.05  # 20 Hz
PHYSICS_DT = 0.002
AGENTVIEW = dict(pos="0.5 0 1.35", quat="0.653 0.271 0.271 0.653")
OBS_MODES = ("low_dim", "image")
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
    )
  )


def policy_obs_size(object_dim: int) -> int:
  """The policy's observation size for a task with an `object` vector of `object_dim` numbers."""
  return sum(ROBOT_OBS_SIZES.values()) + object_dim


def split_policy_obs(obs):
  """(..., D) policy observations -> {key: (..., size)} in `POLICY_OBS_KEYS` order (`object` takes the rest)."""
  out, start = {}, 0
  for k in POLICY_OBS_KEYS:
    size = ROBOT_OBS_SIZES.get(k, obs.shape[-1] - start)
    out[k] = obs[..., start : start + size]
    start += size
  return out


def policy_obs(obs: dict, xp=jnp) -> jax.Array:
  """The policy's observation vector: the four low-dim keys concatenated, (..., 19 or 23); `xp=np` on
  the host."""
  return xp.concatenate([xp.asarray(obs[k], xp.float32) for k in POLICY_OBS_KEYS], axis=-1)


def policy_input(obs: dict, image_keys: tuple[str, ...] = ()):
  """What a policy reads of the observations: the low-dim vector (`policy_obs`), or for a policy of
  camera images (`image_keys`, e.g. `IMAGE_KEYS`) {"lowdim": that vector, "images": {key: (..., H, W,
  3) uint8}}, the form an image policy's observation histories, buffer windows and normaliser take."""
  vector = policy_obs(obs)
  if not image_keys:
    return vector
  missing = [k for k in image_keys if k not in obs]
  if missing:
    raise ValueError(
      f"the policy reads images {', '.join(missing)}, which these observations lack (obs_mode='image' draws them)"
    )
  return {"lowdim": vector, "images": {k: obs[k] for k in image_keys}}


class ManipulationEnv(Env):
  """Panda arm + task scene, 20 Hz absolute end-effector pose control, sparse success reward."""

  name: str = ""
  base_pos: tuple = (-0.56, 0.0, 0.912)
  object_dim: int = 0
  # (kind, size) of the `object` vector's parts: pos, quat (world frame), rel_quat (in the eef frame).
  object_layout: tuple = ()
  agentview: dict = AGENTVIEW
  # The accelerator scene: MJX's own solver options (MuJoCo Playground's Panda tasks use 5 / 8 and
  # pyramidal cones; the C engine keeps the scene's 100 / 50, elliptic), and MuJoCo Warp's buffers
  # per environment, sized at least 1.5x the most any demonstration state uses (`bench mjx`, a test).
  mjx_settings: dict = {"iterations": 10, "ls_iterations": 8, "cone": "pyramidal"}
  mjx_contacts: int = 32
  mjx_constraints: int = 256

  def __init__(self, config: ml_collections.ConfigDict | None = None):
    self.config = config if config is not None else self.default_config()
    self.action_mode = self.config.action_mode
    self._action_size = controller.action_size(self.action_mode)
    self.mj_model = mujoco.MjModel.from_xml_string(self.mjcf())
    self.kin = panda.Kinematics(self.base_pos)
    # wxyz, the hemisphere of `robot0_eef_quat` (module docstring).
    self.hand_reference = np.asarray(
      rotations.mat_to_quat_wxyz(self.kin.forward(jnp.asarray(panda.INIT_QPOS))["hand_rot"])
    )
    self.physics = physics.make_backend(
      self.config.backend,
      self.mj_model,
      self.config.nsubsteps,
      mjx_options=dict(
        impl=self.config.mjx_impl,
        settings=physics.parse_settings(self.config.mjx_settings, self.mjx_settings),
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
    self.cameras = CAMERAS if self.obs_mode == "image" else ()
    self.image_keys = IMAGE_KEYS if self.cameras else ()
    # Started on the first image; `render_seconds` is the time spent drawing, for benchmarks.
    # No multisampling: the images are the policy's input, and llvmpipe draws them 2x faster without.
    self.renderer = pool.Renderer(self.mj_model, self.cameras, self.image_size, samples=0) if self.cameras else None
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

  def _object_obs(self, qpos: jax.Array, eef_pos: jax.Array, hand_rot: jax.Array, hand_quat: jax.Array) -> jax.Array:
    """The task's `object` vector, laid out as `object_layout` says; `hand_quat` is the hand's wxyz
    quaternion in its hemisphere."""
    raise NotImplementedError

  def _success(self, qpos: jax.Array, eef_pos: jax.Array) -> jax.Array:
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
    <camera name="agentview" pos="{cam["pos"]}" quat="{cam["quat"]}" fovy="45"/>
    {panda.robot_mjcf(self.base_pos)}
    {self._scene_mjcf()}
  </worldbody>
  <contact><exclude body1="finger1" body2="finger2"/></contact>
  <actuator>{panda.robot_actuators_mjcf()}</actuator>
</mujoco>"""

  @property
  def observation_size(self) -> int:
    return policy_obs_size(self.object_dim)

  @property
  def obs_layout(self) -> tuple:
    """(kind, size) of every part of the policy observation, in order."""
    return ROBOT_OBS_LAYOUT + tuple(self.object_layout)

  @property
  def obs_min_span(self) -> np.ndarray:
    """(D,) the normaliser's smallest span per policy-observation dimension (`MIN_SPAN`)."""
    return np.concatenate([np.full(size, MIN_SPAN[kind], np.float32) for kind, size in self.obs_layout])

  def conform_quaternions(self, obs: dict) -> dict:
    """One episode's observations {key: (T, .)}, recorded with any quaternion signs, in this task's
    convention (module docstring); observations made here come back unchanged."""
    out = {k: np.array(v) for k, v in obs.items()}
    hand = rotations.same_hemisphere(_wxyz(out["robot0_eef_quat"]), self.hand_reference)
    out["robot0_eef_quat"] = np.asarray(rotations.wxyz_to_xyzw(hand))
    start, world = 0, None
    for kind, size in self.object_layout:
      part = slice(start, start + size)
      if kind == "quat":  # continuous along the episode from w >= 0 at its start
        q = np.asarray(_wxyz(out["object"][:, part]))
        for t in range(len(q)):
          q[t] = rotations.same_hemisphere(q[t], q[t - 1] if t else np.array([1.0, 0, 0, 0]))
        world = q
        out["object"][:, part] = np.asarray(rotations.wxyz_to_xyzw(q))
      elif kind == "rel_quat":  # conj(hand) * object
        expected = rotations.quat_mul_wxyz(rotations.quat_conj_wxyz(hand), world)
        out["object"][:, part] = np.asarray(
          rotations.wxyz_to_xyzw(rotations.same_hemisphere(_wxyz(out["object"][:, part]), expected))
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
    arm = jnp.asarray(panda.INIT_QPOS) + panda.INIT_NOISE * jax.random.normal(key_arm, (7,))
    fingers = jnp.array([panda.FINGER_INIT, -panda.FINGER_INIT])
    return jnp.concatenate([arm, fingers, self._sample_objects(key_obj)]).astype(jnp.float32)

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
    ps = state.pipeline_state
    ctrl = controller.joint_controls(self.kin, self.action_mode, action, ps.qpos[:7])
    ps = self.physics.step(ps, ctrl)
    obs, success = self._observe(ps)
    reward = self._get_reward(success)
    return state.replace(pipeline_state=ps, obs=obs, reward=reward, done=success, metrics={"success": success})

  def _get_reward(self, success: jax.Array) -> jax.Array:
    """Sparse, as robomimic evaluates: 1 on success."""
    return success

  def _observe(self, ps: physics.PhysicsState):
    qpos = ps.qpos
    fk = self.kin.forward(qpos[:7])
    hand_quat = rotations.mat_to_quat_wxyz(fk["hand_rot"], self.hand_reference)
    obs = {
      "robot0_eef_pos": fk["site_pos"],
      "robot0_eef_quat": rotations.wxyz_to_xyzw(hand_quat),
      "robot0_gripper_qpos": qpos[7:9],
      "object": self._object_obs(qpos, fk["site_pos"], fk["hand_rot"], hand_quat),
      "robot0_joint_pos": qpos[:7],
      "robot0_eef_rot": fk["site_rot"].reshape(9),
    }
    if self.cameras:
      obs.update(self._images(qpos))
    return obs, self._success(qpos, fk["site_pos"]).astype(jnp.float32)

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
  q = rotations.same_hemisphere(rotations.yaw_quat_wxyz(yaw), jnp.array([1.0, 0.0, 0.0, 0.0]))
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
