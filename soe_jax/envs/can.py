"""Can: move the can from the source bin into its compartment of the target bin
(robosuite `PickPlaceCan`, `shared/specs/robomimic_tasks.md` 6.2).

Two bins, no table; the robot base at (-0.5, -0.1). The can (radius 0.025, height 0.08) starts
anywhere in x in [-0.02, 0.22], y in [-0.42, -0.08] with a random yaw, resting on the source bin's
floor. Success: the can's center inside the target compartment x in (0.1, 0.295), y in (0.28, 0.525),
0.8 < z < 0.9, and the grip site farther than atanh(0.4) / 10 m from it (released).
`object` = Can_pos, Can_quat (xyzw), Can_to_robot0_eef_pos, Can_to_robot0_eef_quat (the can's pose
in the eef frame).

The other three objects of PickPlace (milk, bread, cereal) are parked outside the scene in robosuite's
single-object variant, so they are left out here. The can collides as a 16-sided convex prism (MJX
has no cylinder-box collisions).
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp

from soe_jax.envs import manipulation, panda, rotations

SOURCE_BIN = (0.1, -0.25, 0.8)
TARGET_BIN = (0.1, 0.28, 0.8)
FLOOR_TOP = 0.82
CAN_RADIUS = 0.025
CAN_HALF_HEIGHT = 0.04
TARGET_BOX = ((0.1, 0.295), (0.28, 0.525))  # x, y bounds of the can's compartment
TARGET_CENTER = (0.1975, 0.4025)
RELEASE_DISTANCE = math.atanh(0.4) / 10.0  # ~0.0424 m
OBJECT_QPOS = 9
# Every position the demonstrator commands from 1,000 start states
# (x [-0.0773, 0.2225], y [-0.4237, 0.3505], z [0.8698, 1.0440]), widened
# by 2 cm on each side (`experts.workspace`):
#   python -m soe_jax experts --task=can --workspace --num_episodes=1000 --seed=90001
WORKSPACE = (((-0.0973, -0.4438, 0.8497), (0.2425, 0.3705, 1.0641)),)


def over_target(pos: jax.Array) -> jax.Array:
  """The can's centre is within the x, y bounds of its target compartment."""
  (x0, x1), (y0, y1) = TARGET_BOX
  return (pos[0] > x0) & (pos[0] < x1) & (pos[1] > y0) & (pos[1] < y1)


def _bin_mjcf(name: str, center, dividers: bool) -> str:
  x, y, z = center
  geoms = [
    ("floor", (0.2, 0.25, 0.02), (0, 0, 0)),
    ("wall_n", (0.21, 0.01, 0.05), (0, 0.25, 0.05)),
    ("wall_s", (0.21, 0.01, 0.05), (0, -0.25, 0.05)),
    ("wall_e", (0.01, 0.25, 0.05), (0.2, 0, 0.05)),
    ("wall_w", (0.01, 0.25, 0.05), (-0.2, 0, 0.05)),
  ]
  if dividers:
    geoms += [("div_x", (0.2, 0.01, 0.05), (0, 0, 0.05)), ("div_y", (0.01, 0.25, 0.05), (0, 0, 0.05))]
  out = [f'<body name="{name}" pos="{x} {y} {z}">']
  for g, size, pos in geoms:
    out.append(
      f'<geom name="{name}_{g}" type="box" size="{manipulation.np_fmt(size)}" pos="{manipulation.np_fmt(pos)}" '
      f'friction="1 0.005 0.0001" {panda.FIXTURE_COLLISION} rgba="0.55 0.4 0.3 1"/>'
    )
  out.append("</body>")
  return "\n".join(out)


class Can(manipulation.ManipulationEnv):
  name = "can"
  bases = (((-0.5, -0.1, 0.912), 0.0),)
  object_dim = 14
  object_layout = (("pos", 3), ("quat", 4), ("pos", 3), ("rel_quat", 4))
  workspace = WORKSPACE
  agentview = dict(pos="1.0 0 1.75", quat="0.653 0.271 0.271 0.653")

  def _assets_mjcf(self) -> str:
    return manipulation.prism_mesh("can_mesh", CAN_RADIUS, CAN_HALF_HEIGHT)

  def _scene_mjcf(self) -> str:
    tx, ty = TARGET_CENTER
    return f"""
    {_bin_mjcf("bin1", SOURCE_BIN, dividers=False)}
    {_bin_mjcf("bin2", TARGET_BIN, dividers=True)}
    <site name="can_target" pos="{tx} {ty} {FLOOR_TOP + CAN_HALF_HEIGHT}" size="0.025 0.04" type="cylinder"
          rgba="0.2 0.8 0.2 0.3" group="2"/>
    <body name="can" pos="0.1 -0.25 {FLOOR_TOP + CAN_HALF_HEIGHT}">
      <freejoint name="can_joint"/>
      <geom name="can" type="mesh" mesh="can_mesh" density="100" condim="4"
            friction="0.95 0.3 0.1" solimp="0.998 0.998 0.001" {panda.OBJECT_COLLISION} rgba="0.75 0.75 0.8 1"/>
    </body>"""

  def _sample_objects(self, key: jax.Array) -> jax.Array:
    key_xy, key_yaw = jax.random.split(key)
    xy = jax.random.uniform(key_xy, (2,), minval=jnp.array([-0.02, -0.42]), maxval=jnp.array([0.22, -0.08]))
    yaw = jax.random.uniform(key_yaw, (), maxval=2 * jnp.pi)
    return manipulation.yaw_free_qpos(jnp.concatenate([xy, jnp.array([FLOOR_TOP + CAN_HALF_HEIGHT])]), yaw)

  def _object_obs(self, qpos, arms):
    arm = arms[0]
    pos, quat = manipulation.free_body_pose(qpos, OBJECT_QPOS)
    rel_pos, rel_quat = manipulation.pose_in_eef(pos, quat, arm.eef_pos, arm.hand_rot, arm.hand_quat)
    return jnp.concatenate([pos, rotations.wxyz_to_xyzw(quat), rel_pos, rel_quat])

  def _success(self, qpos, eef_pos):
    pos = qpos[OBJECT_QPOS : OBJECT_QPOS + 3]
    inside = over_target(pos) & (pos[2] > 0.8) & (pos[2] < 0.9)
    released = jnp.linalg.norm(eef_pos - pos) > RELEASE_DISTANCE
    return inside & released
