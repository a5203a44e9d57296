"""The Panda arm and its parallel-jaw gripper: constants, MJCF, and forward kinematics in JAX.

Kinematics, joint ranges, the initial pose and gripper travel follow robosuite's Panda as used by
robomimic (`shared/specs/robomimic_tasks.md`, sections 2-3). Only the hand and the fingers collide;
the links carry their inertias and visual capsules. Instead of robosuite's operational-space torque
controller, joint position servos with gravity compensation track targets from differential IK
(see `controller.py`).
"""

from __future__ import annotations

import math

import jax.numpy as jnp
import numpy as np

from soe_jax import geometry
from soe_jax.envs import rotations

_S = math.sqrt(0.5)
# (pos, quat wxyz) of link1..link7 relative to the parent body; every joint turns about local z.
LINK_POS = np.array(
  [
    [0, 0, 0.333],
    [0, 0, 0],
    [0, -0.316, 0],
    [0.0825, 0, 0],
    [-0.0825, 0.384, 0],
    [0, 0, 0],
    [0.088, 0, 0],
  ],
  np.float32,
)
LINK_QUAT = np.array(
  [
    [1, 0, 0, 0],
    [_S, -_S, 0, 0],
    [_S, _S, 0, 0],
    [_S, _S, 0, 0],
    [_S, -_S, 0, 0],
    [_S, _S, 0, 0],
    [_S, _S, 0, 0],
  ],
  np.float32,
)
LINK_MASS = [4.0, 3.0, 3.0, 2.0, 2.0, 2.0, 1.5, 0.5]  # link0..link7
LINK_COM = [
  (0, 0, 0.05),
  (0, 0, -0.07),
  (0, -0.1, 0),
  (0.04, 0, -0.05),
  (-0.04, 0.05, 0),
  (0, 0, -0.15),
  (0.06, 0, 0),
  (0, 0, 0.08),
]
LINK_INERTIA = [0.4, 0.3, 0.3, 0.2, 0.2, 0.2, 0.1, 0.05]
JOINT_RANGE = np.array(
  [
    [-2.8973, 2.8973],
    [-1.7628, 1.7628],
    [-2.8973, 2.8973],
    [-3.0718, -0.0698],
    [-2.8973, 2.8973],
    [-0.0175, 3.7525],
    [-2.8973, 2.8973],
  ],
  np.float32,
)
TORQUE_LIMIT = np.array([80, 80, 80, 80, 80, 12, 12], np.float32)
ARMATURE = [5.0 / (i + 1) for i in range(7)]
DAMPING = [0.1] * 5 + [0.01] * 2
INIT_QPOS = np.array([0, math.pi / 16, 0, -math.pi / 2 - math.pi / 3, 0, math.pi - 0.2, math.pi / 4], np.float32)
INIT_NOISE = 0.02  # rad, i.i.d. Gaussian per arm joint at reset
# Position-servo gains: natural frequency ~30 rad/s on the armature-dominated joint inertia, critically damped.
SERVO_KP = np.array([4500, 2700, 2000, 1600, 1350, 1200, 1100], np.float32)
SERVO_KV = 2.0 * np.sqrt(SERVO_KP * (np.array(ARMATURE, np.float32) + 0.25))

HAND_POS = np.array([0, 0, 0.1065], np.float32)
HAND_QUAT = np.array([math.cos(-math.pi / 8), 0, 0, math.sin(-math.pi / 8)], np.float32)  # -45 deg about z
GRIPPER_QUAT = np.array([_S, 0, 0, -_S], np.float32)  # right_gripper: -90 deg about z of the hand
GRIP_SITE_POS = np.array([0, 0, 0.097], np.float32)  # in right_gripper
FINGER_Z = 0.0524
FINGER_TRAVEL = 0.04  # each finger slides 0..0.04 m; -1 (open) commands 0.04, +1 (closed) 0
FINGER_INIT = 0.020833
FINGER_KP = 1000.0
FINGER_FORCE = 20.0
NUM_ARM_JOINTS = 7
NUM_ROBOT_QPOS = 9  # 7 arm joints + 2 finger slides, first in qpos

# Collision bits: objects collide with everything, fixtures with objects and the gripper,
# the gripper with objects and fixtures; nothing else collides (arm links are visual only).
# Fixtures (table, bins, pegs, floor) take priority in their contacts and use condim 3: an object
# resting on a face gets its resistance to spinning from the several corner contacts already, so a
# torsional term per contact would add solver rows, not behaviour (measured: square x 256
# environments, +30% control steps per second). Their sliding friction (1) equals what robosuite's
# max-mixing gives. Grasps keep the pads' condim 4.
OBJECT_COLLISION = 'contype="1" conaffinity="1"'
FIXTURE_COLLISION = 'contype="2" conaffinity="1" priority="1" condim="3"'
GRIPPER_COLLISION = 'contype="4" conaffinity="3"'
VISUAL = 'contype="0" conaffinity="0" group="1"'
EYE_IN_HAND = "robot0_eye_in_hand"  # the camera on the hand (robomimic's `robot0_eye_in_hand_image`)


def _fmt(v) -> str:
  return " ".join(f"{float(x):.6g}" for x in np.ravel(v))


def prefix(index: int) -> str:
  """Robot `index`'s prefix for body, joint, geom, site and actuator names: none for robot0 (the
  single-arm tasks' names), `robot<index>_` for the others."""
  return f"robot{index}_" if index else ""


def eye_in_hand(index: int) -> str:
  """The wrist camera of robot `index` (robomimic's `robot<index>_eye_in_hand_image`)."""
  return f"robot{index}_eye_in_hand"


def robot_mjcf(base_pos, base_yaw: float = 0.0, index: int = 0) -> str:
  """MJCF for the arm, hand and fingers of robot `index`, to be placed in `<worldbody>`, base at
  `base_pos` turned by `base_yaw` about world z."""
  n = prefix(index)
  link_vis = [  # fromto capsules from each link origin towards the next joint, for rendering only
    "0 0 0 0 0 0.333",
    "0 0 -0.05 0 0 0.05",
    "0 0 0 0 -0.316 0",
    "0 0 0 0.0825 0 0",
    "0 0 0 -0.0825 0.384 0",
    "0 0 -0.1 0 0 0.05",
    "0 0 0 0.088 0 0",
    "0 0 0 0 0 0.1065",
  ]
  xml = [
    f'<body name="{n}link0" pos="{_fmt(base_pos)}" quat="{_fmt(np.asarray(rotations.yaw_quat_wxyz(base_yaw)))}">',
    f'<inertial pos="{_fmt(LINK_COM[0])}" mass="{LINK_MASS[0]}" diaginertia="{_fmt([LINK_INERTIA[0]] * 3)}"/>',
    f'<geom type="capsule" size="0.06" fromto="{link_vis[0]}" {VISUAL} rgba="1 1 1 1"/>',
    '<geom type="cylinder" size="0.18 0.31" pos="0 0 -0.6" ' + VISUAL + ' rgba="0.2 0.2 0.2 1"/>',
  ]
  for i in range(7):
    lo, hi = JOINT_RANGE[i]
    xml.append(f'<body name="{n}link{i + 1}" pos="{_fmt(LINK_POS[i])}" quat="{_fmt(LINK_QUAT[i])}" gravcomp="1">')
    xml.append(
      f'<inertial pos="{_fmt(LINK_COM[i + 1])}" mass="{LINK_MASS[i + 1]}" '
      f'diaginertia="{_fmt([LINK_INERTIA[i + 1]] * 3)}"/>'
    )
    xml.append(
      f'<joint name="{n}joint{i + 1}" type="hinge" axis="0 0 1" range="{lo} {hi}" '
      f'damping="{DAMPING[i]}" armature="{ARMATURE[i]:.6g}" frictionloss="0.1"/>'
    )
    xml.append(f'<geom type="capsule" size="0.05" fromto="{link_vis[i + 1]}" {VISUAL} rgba="1 1 1 1"/>')
  xml.append(f'<body name="{n}right_hand" pos="{_fmt(HAND_POS)}" quat="{_fmt(HAND_QUAT)}" gravcomp="1">')
  xml.append('<inertial pos="0 0 0" mass="0.5" diaginertia="0.05 0.05 0.05"/>')
  # robosuite's wrist camera, looking out along the approach axis between the fingers.
  xml.append(f'<camera name="{eye_in_hand(index)}" pos="0.05 0 0" quat="0 0.707108 0.707108 0" fovy="75"/>')
  xml.append(f'<body name="{n}right_gripper" quat="{_fmt(GRIPPER_QUAT)}" gravcomp="1">')
  xml.append('<inertial pos="0 0 0.04" mass="0.3" diaginertia="0.001 0.001 0.001"/>')
  # Palm: its bottom face sits 31 mm behind the grip site, along the approach axis (local z).
  xml.append(
    f'<geom name="{n}hand" type="box" size="0.03 0.1 0.0225" pos="0 0 0.0435" {GRIPPER_COLLISION} '
    'friction="1 0.005 0.0001" rgba="0.9 0.9 0.9 1"/>'
  )
  xml.append(f'<site name="{n}grip_site" pos="{_fmt(GRIP_SITE_POS)}" size="0.005" rgba="1 0 0 0.5" group="2"/>')
  # The finger bodies are turned back +90 deg, so they slide along the hand's y axis, which is
  # the grip site's x axis (the closing axis).
  for side, sign in (("finger1", 1), ("finger2", -1)):
    lo, hi = (0.0, FINGER_TRAVEL) if sign > 0 else (-FINGER_TRAVEL, 0.0)
    xml.append(f'<body name="{n}{side}" pos="0 0 {FINGER_Z}" quat="{_fmt([_S, 0, 0, _S])}" gravcomp="1">')
    xml.append('<inertial pos="0 0 0.03" mass="0.1" diaginertia="0.0001 0.0001 0.0001"/>')
    xml.append(
      f'<joint name="{n}{side}_joint" type="slide" axis="0 1 0" range="{lo} {hi}" damping="100" '
      'armature="1.0" frictionloss="1.0"/>'
    )
    # Finger body behind the pad (outer side) and the pad whose inner face is at y = 0 of the body.
    xml.append(
      f'<geom type="box" size="0.009 0.007 0.02" pos="0 {sign * 0.012} 0.034" {GRIPPER_COLLISION} '
      'friction="1 0.005 0.0001" rgba="0.9 0.9 0.9 1"/>'
    )
    xml.append(
      f'<geom name="{n}{side}_pad" type="box" size="0.008 0.004 0.008" pos="0 {sign * 0.004} 0.0446" '
      f'{GRIPPER_COLLISION} condim="4" friction="2 0.05 0.0001" solref="0.01 0.5" rgba="0.3 0.3 0.3 1"/>'
    )
    xml.append("</body>")
  xml.append("</body></body>")
  xml.append("</body>" * 7)
  xml.append("</body>")
  return "\n".join(xml)


def robot_actuators_mjcf(index: int = 0) -> str:
  """Joint position servos (arm) and force-limited finger servos of robot `index`."""
  n, xml = prefix(index), []
  for i in range(7):
    lo, hi = JOINT_RANGE[i]
    xml.append(
      f'<position name="{n}act{i + 1}" joint="{n}joint{i + 1}" kp="{SERVO_KP[i]:.6g}" kv="{SERVO_KV[i]:.6g}" '
      f'ctrlrange="{lo} {hi}" forcerange="{-TORQUE_LIMIT[i]} {TORQUE_LIMIT[i]}"/>'
    )
  xml.append(
    f'<position name="{n}act_finger1" joint="{n}finger1_joint" kp="{FINGER_KP}" ctrlrange="0 {FINGER_TRAVEL}" '
    f'forcerange="{-FINGER_FORCE} {FINGER_FORCE}"/>'
  )
  xml.append(
    f'<position name="{n}act_finger2" joint="{n}finger2_joint" kp="{FINGER_KP}" ctrlrange="{-FINGER_TRAVEL} 0" '
    f'forcerange="{-FINGER_FORCE} {FINGER_FORCE}"/>'
  )
  return "\n".join(xml)


def _transform(pos, quat):
  return jnp.asarray(pos), geometry.quat_wxyz_to_mat(jnp.asarray(quat))


class Kinematics:
  """Forward kinematics of the arm in JAX for a base at `base_pos` turned by `base_yaw` about world z."""

  def __init__(self, base_pos, base_yaw: float = 0.0):
    self.base_pos = jnp.asarray(base_pos, jnp.float32)
    self.base_rot = rotations.rotz(jnp.float32(base_yaw))
    self._link = [_transform(LINK_POS[i], LINK_QUAT[i]) for i in range(7)]
    hand_p, hand_r = _transform(HAND_POS, HAND_QUAT)
    grip_r = geometry.quat_wxyz_to_mat(jnp.asarray(GRIPPER_QUAT))
    self._hand = (hand_p, hand_r)
    self._grip_r = grip_r

  def forward(self, q: jnp.ndarray):
    """(7,) joint angles -> dict of site position (3,), site rotation (3, 3), hand rotation (3, 3),
    and the site Jacobian (6, 7) in the world frame (linear rows first)."""
    p = self.base_pos
    r = self.base_rot
    axes, origins = [], []
    for i in range(7):
      lp, lr = self._link[i]
      p = p + r @ lp
      r = r @ lr
      axes.append(r[:, 2])
      origins.append(p)
      r = r @ rotations.rotz(q[i])
    hp, hr = self._hand
    p_hand = p + r @ hp
    r_hand = r @ hr
    r_site = r_hand @ self._grip_r
    p_site = p_hand + r_site @ jnp.asarray(GRIP_SITE_POS)
    axes = jnp.stack(axes, 1)  # (3, 7)
    origins = jnp.stack(origins, 1)
    jac_pos = jnp.cross(axes.T, (p_site[:, None] - origins).T).T
    return dict(site_pos=p_site, site_rot=r_site, hand_rot=r_hand, jac=jnp.concatenate([jac_pos, axes], 0))
