"""Transport: two arms move the hammer from the start bin to the target bin, and the trash cube to the
trash bin (robosuite `TwoArmTransport`, `shared/specs/robomimic_tasks.md` 6.4).

Two tables (0.8 x 0.3, top at z = 0.8) at y = -0.45 and +0.45, a Panda behind each: robot0 at
(0, -0.81) facing +y, robot1 at (0, +0.81) facing -y. On robot0's table the start bin (x = +0.2)
under its lid, with the hammer (the payload) inside; on robot1's table the target bin (x = -0.2),
holding the trash cube, and the trash bin (x = +0.2). Bins are open boxes 0.30 x 0.30 x 0.15 with 1 cm
walls and a base plate whose top is at z = 0.811. One arm takes the lid off and picks the hammer up,
the arms hand it over, the other places it in the target bin, and the trash goes to the trash bin.

Start states: lid, hammer and trash each +-5 mm in x and y about their bin's centre, 1 mm above where
they rest; the lid unturned, the trash cube's yaw in [-0.3 pi, 0.3 pi], the hammer lying flat with its
handle along world +y or -y (either end, 50/50) and a yaw in [-pi/6, pi/6].

Success: the hammer rests on the target bin's base plate and the trash cube on the trash bin's.
robosuite checks contacts with the base plates; here, as a function of the joint positions alone (the
same on both backends), an object is on a plate when its lowest corner is within `ON_PLATE` of the
plate's top and its centre is inside the bin's walls.

`object` (41 numbers, robomimic's order): payload_pos, payload_quat (xyzw), trash_pos, trash_quat,
lid_handle_pos, lid_handle_quat, target_bin_pos, trash_bin_pos, gripper0_to_payload,
gripper0_to_lid_handle, gripper1_to_payload, gripper1_to_trash (each object - eef, world frame),
payload_in_target_bin, trash_in_trash_bin (0 / 1, the two halves of success).

Deviations, each so that a batch of environments shares one model on both backends and stays cheap
on MJX: the bins are fixtures at their nominal places (robosuite's are 26 kg free bodies placed
+-5 mm, so `target_bin_pos` and `trash_bin_pos` are constants here); the hammer is its handle and a
head box of fixed size (robosuite draws the head's size from [0.015, 0.018] on every reset and adds
neck, face and claw shapes); the grippers of the two arms do not collide with each other.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np

from soe_jax import geometry
from soe_jax.envs import manipulation, panda, rotations

TABLE_TOP = 0.8
TABLE_Y = 0.45
BIN_Z = 0.876  # the bins' centres; base plates at -0.07 of it, walls 0.15 high
START_BIN = (0.2, -TABLE_Y, BIN_Z)
TARGET_BIN = (-0.2, TABLE_Y, BIN_Z)
TRASH_BIN = (0.2, TABLE_Y, BIN_Z)
BIN_HALF = 0.15
WALL_HALF = 0.005
PLATE_TOP = BIN_Z - 0.065  # 0.811
INNER_HALF = BIN_HALF - 2 * WALL_HALF  # 0.14: inside the walls
# Every position each robot's demonstrator commands from 1,000 start states
#   robot0: x [-0.2224, 0.2224], y [-0.4897, -0.0168], z [0.8241, 1.1261]
#   robot1: x [-0.2118, 0.2332], y [-0.0022, 0.4891], z [0.8254, 1.1242]
# widened by 2 cm on each side (`experts.workspace`):
#   python -m soe_jax experts --task=transport --workspace --num_episodes=1000 --seed=90001
WORKSPACE = (
  ((-0.2425, -0.5098, 0.8041), (0.2425, 0.0033, 1.1461)),
  ((-0.2319, -0.0222, 0.8054), (0.2532, 0.5092, 1.1442)),
)
WALL_TOP = BIN_Z + 0.075
LID_PLATE = (0.15, 0.15, 0.005)  # half-extents
LID_HANDLE = (0.01, 0.04, 0.015)
LID_HANDLE_OFFSET = LID_PLATE[2] + LID_HANDLE[2]  # the handle's centre above the plate's
HAMMER_HANDLE = (0.015, 0.015, 0.1)  # half-extents, along the body's z
HEAD = 0.0165  # robosuite's head size h, the middle of [0.015, 0.018]: a 4h x 2h x 2h box
HAMMER_HEAD = (2 * HEAD, HEAD, HEAD)
HAMMER_HEAD_OFFSET = HAMMER_HANDLE[2] + HEAD
TRASH_HALF = 0.02
# Beside and above robot0's shoulder, looking at its table (robot1's: the same turned half a turn about z).
SHOULDER_CAMERA = (0.5, -1.05, 1.55)
JITTER = 0.005
DROP = 0.001
ON_PLATE = 0.005  # an object's lowest corner this close to a plate's top rests on it
# Free joints' qpos: two robots' 9 each, then the lid, the hammer, the trash cube (7 each).
LID_QPOS, PAYLOAD_QPOS, TRASH_QPOS = 18, 25, 32
# Boxes of each free body, (centre in the body frame, half-extents), for the rest checks.
PAYLOAD_BOXES = (((0.0, 0.0, 0.0), HAMMER_HANDLE), ((0.0, 0.0, HAMMER_HEAD_OFFSET), HAMMER_HEAD))
TRASH_BOXES = (((0.0, 0.0, 0.0), (TRASH_HALF,) * 3),)


def _box(name: str, size, pos, extra: str, rgba: str) -> str:
  fmt = manipulation.np_fmt
  return f'<geom name="{name}" type="box" size="{fmt(size)}" pos="{fmt(pos)}" {extra} rgba="{rgba}"/>'


def _bin_mjcf(name: str, center, rgba: str) -> str:
  """An open box of 1 cm walls on a base plate, fixed to the table (`PLATE_TOP`, `INNER_HALF`)."""
  x, y, z = center
  wall, h = WALL_HALF, 0.075
  parts = [
    ("plate", (BIN_HALF - wall, BIN_HALF - wall, 0.005), (0, 0, -0.07)),
    ("wall_n", (BIN_HALF, wall, h), (0, BIN_HALF - wall, 0)),
    ("wall_s", (BIN_HALF, wall, h), (0, -(BIN_HALF - wall), 0)),
    ("wall_e", (wall, BIN_HALF - 2 * wall, h), (BIN_HALF - wall, 0, 0)),
    ("wall_w", (wall, BIN_HALF - 2 * wall, h), (-(BIN_HALF - wall), 0, 0)),
  ]
  fixture = f'friction="1 0.005 0.0001" {panda.FIXTURE_COLLISION}'
  geoms = "\n".join(_box(f"{name}_{part}", size, pos, fixture, rgba) for part, size, pos in parts)
  return f'<body name="{name}" pos="{x} {y} {z}">\n{geoms}\n</body>'


def look_at(pos, target) -> str:
  """A camera's `xyaxes` at `pos` looking at `target`, level (image rows horizontal)."""
  forward = np.subtract(target, pos) / np.linalg.norm(np.subtract(target, pos))
  right = np.cross(forward, (0.0, 0.0, 1.0))
  right /= np.linalg.norm(right)
  return manipulation.np_fmt(np.concatenate([right, np.cross(right, forward)]))


def _quat_x(angle) -> jax.Array:
  """Rotation about x by `angle`, wxyz."""
  h = 0.5 * angle
  return jnp.stack([jnp.cos(h), jnp.sin(h), jnp.zeros_like(h), jnp.zeros_like(h)])


def lowest_point(pos: jax.Array, quat: jax.Array, boxes) -> jax.Array:
  """The lowest z of a free body's boxes at pose (pos, wxyz quat)."""
  rot = geometry.quat_wxyz_to_mat(quat)
  reach = jnp.abs(rot[2])  # how far each body axis reaches along world z per unit length
  return jnp.min(jnp.stack([pos[2] + rot[2] @ jnp.asarray(c) - reach @ jnp.asarray(h) for c, h in boxes]))


def on_plate(pos: jax.Array, quat: jax.Array, boxes, bin_center) -> jax.Array:
  """The body rests on the bin's base plate: its centre inside the walls, its lowest corner on the plate."""
  inside = jnp.all(jnp.abs(pos[:2] - jnp.asarray(bin_center[:2])) < INNER_HALF)
  return inside & (lowest_point(pos, quat, boxes) < PLATE_TOP + ON_PLATE)


class Transport(manipulation.ManipulationEnv):
  name = "transport"
  bases = (((0.0, -0.81, 0.912), math.pi / 2), ((0.0, 0.81, 0.912), -math.pi / 2))
  object_dim = 41
  workspace = WORKSPACE
  object_layout = (
    ("pos", 3),
    ("quat", 4),
    ("pos", 3),
    ("quat", 4),
    ("pos", 3),
    ("quat", 4),
    ("pos", 3),
    ("pos", 3),
    ("pos", 3),
    ("pos", 3),
    ("pos", 3),
    ("pos", 3),
    ("flag", 1),
    ("flag", 1),
  )
  # From the side (+x), both tables in view; robomimic's image keys are the shoulder and wrist cameras.
  agentview = dict(pos="1.3 0 1.6", xyaxes=look_at((1.3, 0, 1.6), (0, 0, TABLE_TOP)))
  image_cameras = ("shouldercamera0", "shouldercamera1", panda.eye_in_hand(0), panda.eye_in_hand(1))
  mjx_contacts = 96
  mjx_constraints = 768

  @classmethod
  def default_config(cls):
    config = manipulation.base_config()
    config.episode_length = 700  # robomimic's evaluation horizon for transport
    return config

  def _scene_mjcf(self) -> str:
    fixture = f'friction="1 0.005 0.0001" {panda.FIXTURE_COLLISION}'
    tables = "\n".join(
      _box(f"table{k}", (0.4, 0.15, 0.025), (0, y, TABLE_TOP - 0.025), fixture, "0.8 0.7 0.6 1")
      for k, y in enumerate((-TABLE_Y, TABLE_Y))
    )
    obj = panda.OBJECT_COLLISION
    lid_z, handle_z = WALL_TOP + LID_PLATE[2] + DROP, LID_HANDLE_OFFSET
    payload_z = PLATE_TOP + HEAD + DROP
    return f"""
    {tables}
    <camera name="shouldercamera0" pos="{manipulation.np_fmt(SHOULDER_CAMERA)}" fovy="45"
            xyaxes="{look_at(SHOULDER_CAMERA, (0, -TABLE_Y, TABLE_TOP))}"/>
    <camera name="shouldercamera1" pos="{manipulation.np_fmt(np.multiply(SHOULDER_CAMERA, (-1, -1, 1)))}" fovy="45"
            xyaxes="{look_at(np.multiply(SHOULDER_CAMERA, (-1, -1, 1)), (0, TABLE_Y, TABLE_TOP))}"/>
    {_bin_mjcf("start_bin", START_BIN, "0.55 0.4 0.3 1")}
    {_bin_mjcf("target_bin", TARGET_BIN, "0.3 0.45 0.3 1")}
    {_bin_mjcf("trash_bin", TRASH_BIN, "0.35 0.35 0.4 1")}
    <body name="lid" pos="{START_BIN[0]} {START_BIN[1]} {lid_z}">
      <freejoint name="lid_joint"/>
      {_box("lid_plate", LID_PLATE, (0, 0, 0), f'density="250" friction="1 0.005 0.0001" {obj}', "0.6 0.5 0.4 1")}
      {_box("lid_handle", LID_HANDLE, (0, 0, handle_z), f'density="500" friction="1 0.005 0.0001" {obj}', "0.2 0.2 0.6 1")}
    </body>
    <body name="payload" pos="{START_BIN[0]} {START_BIN[1]} {payload_z}" quat="0.7071068 0.7071068 0 0">
      <freejoint name="payload_joint"/>
      {_box("payload_handle", HAMMER_HANDLE, (0, 0, 0), f'density="150" friction="4 0.005 0.0001" {obj}', "0.7 0.45 0.2 1")}
      {_box("payload_head", HAMMER_HEAD, (0, 0, HAMMER_HEAD_OFFSET), f'density="225" friction="1 0.005 0.0001" {obj}', "0.3 0.3 0.3 1")}
    </body>
    <body name="trash" pos="{TARGET_BIN[0]} {TARGET_BIN[1]} {PLATE_TOP + TRASH_HALF + DROP}">
      <freejoint name="trash_joint"/>
      {_box("trash", (TRASH_HALF,) * 3, (0, 0, 0), f'density="1000" friction="1 0.005 0.0001" {obj}', "0.8 0.1 0.1 1")}
    </body>"""

  def _sample_objects(self, key: jax.Array) -> jax.Array:
    key_lid, key_payload, key_trash, key_yaw, key_trash_yaw, key_end = jax.random.split(key, 6)
    jitter = lambda k, center: jnp.asarray(center[:2]) + jax.random.uniform(k, (2,), minval=-JITTER, maxval=JITTER)
    lid = manipulation.yaw_free_qpos(jnp.append(jitter(key_lid, START_BIN), WALL_TOP + LID_PLATE[2] + DROP), 0.0)
    # Lying flat, the handle along world y, the head at either end: a quarter turn about x either way
    # (the body's z, handle to head, to world -y or +y), then a yaw.
    end = jnp.where(jax.random.bernoulli(key_end), 1.0, -1.0)
    yaw = jax.random.uniform(key_yaw, (), minval=-math.pi / 6, maxval=math.pi / 6)
    payload_quat = rotations.quat_mul_wxyz(rotations.yaw_quat_wxyz(yaw), _quat_x(end * math.pi / 2))
    payload = jnp.concatenate([jnp.append(jitter(key_payload, START_BIN), PLATE_TOP + HEAD + DROP), payload_quat])
    trash_yaw = jax.random.uniform(key_trash_yaw, (), minval=-0.3 * math.pi, maxval=0.3 * math.pi)
    trash = manipulation.yaw_free_qpos(
      jnp.append(jitter(key_trash, TARGET_BIN), PLATE_TOP + TRASH_HALF + DROP), trash_yaw
    )
    return jnp.concatenate([lid, payload, trash])

  def _object_obs(self, qpos, arms):
    payload_pos, payload_quat = manipulation.free_body_pose(qpos, PAYLOAD_QPOS)
    trash_pos, trash_quat = manipulation.free_body_pose(qpos, TRASH_QPOS)
    lid_pos, lid_quat = manipulation.free_body_pose(qpos, LID_QPOS)
    handle_pos = lid_pos + geometry.quat_wxyz_to_mat(lid_quat)[:, 2] * LID_HANDLE_OFFSET
    eef0, eef1 = arms[0].eef_pos, arms[1].eef_pos
    in_target, in_trash = self._placed(qpos)
    return jnp.concatenate(
      [
        payload_pos,
        rotations.wxyz_to_xyzw(payload_quat),
        trash_pos,
        rotations.wxyz_to_xyzw(trash_quat),
        handle_pos,
        rotations.wxyz_to_xyzw(lid_quat),
        jnp.asarray(TARGET_BIN, jnp.float32),
        jnp.asarray(TRASH_BIN, jnp.float32),
        payload_pos - eef0,
        handle_pos - eef0,
        payload_pos - eef1,
        trash_pos - eef1,
        jnp.stack([in_target, in_trash]).astype(jnp.float32),
      ]
    )

  def _placed(self, qpos):
    """(hammer on the target bin's plate, trash cube on the trash bin's plate)."""
    payload = on_plate(*manipulation.free_body_pose(qpos, PAYLOAD_QPOS), PAYLOAD_BOXES, TARGET_BIN)
    trash = on_plate(*manipulation.free_body_pose(qpos, TRASH_QPOS), TRASH_BOXES, TRASH_BIN)
    return payload, trash

  def _success(self, qpos, eef_pos):
    payload, trash = self._placed(qpos)
    return payload & trash


def payload_pose(pos, yaw: float, end: float = 1.0) -> np.ndarray:
  """Free-joint qpos (7,) of the hammer lying flat with its handle's centre at `pos`, head towards
  world +y (`end` = 1) or -y (-1) before the `yaw` about z (for hand-placed states)."""
  quat = rotations.quat_mul_wxyz(rotations.yaw_quat_wxyz(jnp.float32(yaw)), _quat_x(jnp.float32(-end * math.pi / 2)))
  return np.concatenate([np.asarray(pos, np.float32), np.asarray(quat)])
