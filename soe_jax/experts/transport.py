"""Transport demonstrator: one script per arm, meeting at a handover over the gap between the tables.

robot0: takes the lid off the start bin by its handle and puts it down beside the bin, picks the hammer
up by its handle (the half towards robot0), turns it so the handle runs along world y, holds it out
over the gap, and lets go once robot1 has it; then it moves up and back.
robot1 meanwhile: picks the trash cube out of the target bin and drops it into the trash bin, waits
above the handover, and once the hammer is there grasps the handle's other half, waits for robot0 to
let go and clear, and lowers the hammer into the target bin.

Each arm's phases read only the observation, so either arm resumes from any scene (`resume_*`), and
the waits are the observation's too (robot1 descends once the hammer is held out; robot0 opens once
robot1's fingers are closed on the handle; robot1 leaves once robot0's are open and above it).

`EXPERT` is the scripted demonstrator; `VARIED` draws human-like styles per episode and arm (Lift's,
`lift.sample_styles`): robot0's approaches to the lid and to the hammer and its carry of the lid, and
robot1's approach to the trash, its carry to the trash bin and its carry of the hammer to the target
bin, each straight or arced to either side with an occasional hover at its end; each arm's speed from
Lift's wider range and its descents at their own pace; robot1's grasp on either pair of the trash
cube's faces. The handover itself is the scripted
one (the two hands meet there).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from soe_jax import geometry
from soe_jax.envs import rotations
from soe_jax.envs import transport as task
from soe_jax.experts import lift as lift_expert
from soe_jax.experts import script
from soe_jax.experts.script import always, target, uniform

# Where each arm grasps the handle, from the hammer's centre towards its own side. The palm reaches
# 0.1 m along the handle either side of the grasp, and the start bin's walls 0.14 m from its centre, so
# robot0's grasp stays near the centre; the two grasps are 6.5 cm apart at the handover.
GRASP0, GRASP1 = 0.03, 0.035
# Where robot0 holds the hammer's centre out: midway between the bases (0.81 m from each), which the
# grasps either side of it keep within both arms' reach (about 0.80 m for a top-down hand).
HANDOVER = (0.0, 0.0, 1.0)
LID_ASIDE = (-0.2, -task.TABLE_Y)  # the lid goes down on robot0's table, beside the start bin
CARRY_Z = 1.05
# Objects are let go into a bin with the palm (its face 31 mm behind the grip site, 0.1 m either side
# of the grasp) just above the walls, so that it cannot catch on them.
DROP_Z = task.WALL_TOP + 0.01 - 0.031
LID_LIFT_Z = 1.1


# -- the scene, as the observation shows it ---------------------------------------------------------
def _payload(obs):
  """(centre (3,), handle-to-head axis (3,)) of the hammer."""
  q = obs["object"][3:7]
  return obs["object"][:3], geometry.quat_wxyz_to_mat(jnp.stack([q[3], q[0], q[1], q[2]]))[:, 2]


def _grasp_point(obs, side: float, offset: float):
  """The point on the handle `offset` from the centre towards world -y (`side` = -1, robot0's) or +y."""
  centre, axis = _payload(obs)
  towards_y = jnp.where(axis[1] >= 0, 1.0, -1.0)
  return centre + side * towards_y * offset * axis


def _across_handle(obs, cmd_yaw):
  """The grasp yaw closing across the handle, the equivalent nearest `cmd_yaw`."""
  _, axis = _payload(obs)
  return script.nearest_equivalent(jnp.arctan2(axis[1], axis[0]) + jnp.pi / 2, cmd_yaw, jnp.pi)


def holding_hammer(obs, robot: int) -> jax.Array:
  """Robot `robot`'s fingers are closed on the handle, its grip site on the handle's axis."""
  centre, axis = _payload(obs)
  rel = obs[f"robot{robot}_eef_pos"] - centre
  along = rel @ axis
  off_axis = jnp.linalg.norm(rel - along * axis)
  closed = obs[f"robot{robot}_gripper_qpos"][0] < task.HAMMER_HANDLE[0] + 0.004
  return (off_axis < 0.015) & (jnp.abs(along) < task.HAMMER_HANDLE[2]) & closed


def hammer_held_out(obs) -> jax.Array:
  """The hammer is over the gap at the handover, its handle along world y."""
  centre, axis = _payload(obs)
  near = jnp.linalg.norm(centre[:2] - jnp.asarray(HANDOVER[:2])) < 0.04
  return near & (jnp.abs(axis[1]) > 0.95) & (centre[2] > HANDOVER[2] - 0.08)


def _lid_on_bin(obs):
  handle = obs["object"][14:17]
  return script.near_xy(handle, jnp.asarray(task.START_BIN), 0.03) & (handle[2] > task.WALL_TOP)


def _in_bin(pos, center):
  return jnp.all(jnp.abs(pos[:2] - jnp.asarray(center[:2])) < task.INNER_HALF) & (pos[2] < task.WALL_TOP)


def _robot0_open_and_clear(obs, p):
  centre, _ = _payload(obs)
  is_open = obs["robot0_gripper_qpos"][0] > 0.03
  return is_open & (obs["robot0_eef_pos"][2] > centre[2] + 0.05)


def _robot1_holds(obs, p):
  return holding_hammer(obs, 1)


def _held_out(obs, p):
  return hammer_held_out(obs)


# -- robot0: the lid, then the hammer to the handover --------------------------------------------
def params0(key):
  k = jax.random.split(key, 9)
  return dict(
    speed=uniform(k[0], 0.009, 0.014),
    settle=jax.random.randint(k[1], (), 2, 10),
    height=uniform(k[2], 0.06, 0.10),
    offset=uniform(k[3], -0.003, 0.003, (2,)),
    grasp_dz=uniform(k[4], 0.0, 0.005),
    close=jax.random.randint(k[5], (), 5, 10),
    aside=uniform(k[6], -0.02, 0.02, (2,)),
    handover=uniform(k[7], jnp.array([-0.02, -0.008, -0.02]), jnp.array([0.02, 0.008, 0.02]), (3,)),
    yaw=uniform(k[8], -0.1, 0.1),
  )


def settle0(obs, p, cmd_pos, cmd_yaw):
  return target(cmd_pos, cmd_yaw, -1.0, p["speed"], hold=p["settle"])


def above_lid(obs, p, cmd_pos, cmd_yaw):
  handle, lid_yaw = obs["object"][14:17], script.quat_yaw_xyzw(obs["object"][17:21])
  pos = handle + jnp.concatenate([p["offset"], p["height"][None]])
  return target(pos, script.nearest_equivalent(lid_yaw + p["yaw"], cmd_yaw, jnp.pi), -1.0, p["speed"], tol=0.015)


def descend_lid(obs, p, cmd_pos, cmd_yaw):
  pos = obs["object"][14:17] + jnp.concatenate([p["offset"], p["grasp_dz"][None]])
  return target(pos, cmd_yaw, -1.0, 0.6 * p["speed"], hold=1, tol=0.008)


def close(obs, p, cmd_pos, cmd_yaw):
  return target(cmd_pos, cmd_yaw, 1.0, p["speed"], hold=p["close"], tol=0.02)


def lift_lid(obs, p, cmd_pos, cmd_yaw):
  return target(cmd_pos.at[2].set(LID_LIFT_Z), cmd_yaw, 1.0, p["speed"], tol=0.02)


def lid_aside(obs, p, cmd_pos, cmd_yaw):
  pos = jnp.concatenate([jnp.asarray(LID_ASIDE) + p["aside"], jnp.array([LID_LIFT_Z])])
  return target(pos, cmd_yaw, 1.0, p["speed"], tol=0.02)


def lower_lid(obs, p, cmd_pos, cmd_yaw):
  rest = task.TABLE_TOP + 2 * task.LID_PLATE[2] + task.LID_HANDLE[2] + 0.01
  return target(cmd_pos.at[2].set(rest), cmd_yaw, 1.0, 0.7 * p["speed"], tol=0.015)


def release(obs, p, cmd_pos, cmd_yaw):
  return target(cmd_pos, cmd_yaw, -1.0, p["speed"], hold=4, tol=0.03)


def up(obs, p, cmd_pos, cmd_yaw):
  return target(cmd_pos.at[2].set(CARRY_Z), cmd_yaw, -1.0, p["speed"], tol=0.02)


def above_hammer(obs, p, cmd_pos, cmd_yaw):
  grasp = _grasp_point(obs, -1.0, GRASP0)
  pos = jnp.concatenate([grasp[:2] + p["offset"], (task.WALL_TOP + p["height"])[None]])
  return target(pos, _across_handle(obs, cmd_yaw), -1.0, p["speed"], tol=0.015)


def descend_hammer(obs, p, cmd_pos, cmd_yaw):
  grasp = _grasp_point(obs, -1.0, GRASP0)
  pos = jnp.concatenate([grasp[:2] + p["offset"], (grasp[2] + p["grasp_dz"])[None]])
  return target(pos, cmd_yaw, -1.0, 0.6 * p["speed"], hold=1, tol=0.008)


def lift_hammer(obs, p, cmd_pos, cmd_yaw):
  return target(cmd_pos.at[2].set(CARRY_Z), cmd_yaw, 1.0, p["speed"], tol=0.02)


def to_handover(obs, p, cmd_pos, cmd_yaw):
  """Turn the handle onto world y and bring the hammer's centre to the handover point."""
  centre, axis = _payload(obs)
  heading = jnp.arctan2(axis[1], axis[0])
  turn = jnp.where(axis[1] >= 0, jnp.pi / 2, -jnp.pi / 2) - heading
  eef = obs["robot0_eef_pos"]
  grip_from_centre = rotations.rotz(turn) @ (eef - centre)
  pos = jnp.asarray(HANDOVER) + p["handover"] + grip_from_centre
  return target(pos, cmd_yaw + turn, 1.0, 0.8 * p["speed"], tol=0.015)


def hold_out(obs, p, cmd_pos, cmd_yaw):
  return target(cmd_pos, cmd_yaw, 1.0, p["speed"], hold=3, tol=0.03)


def let_go(obs, p, cmd_pos, cmd_yaw):
  return target(cmd_pos, cmd_yaw, -1.0, p["speed"], hold=6, tol=0.03)


def rise(obs, p, cmd_pos, cmd_yaw):
  return target(cmd_pos.at[2].add(0.1), cmd_yaw, -1.0, p["speed"], tol=0.02)


def back0(obs, p, cmd_pos, cmd_yaw):
  return target(jnp.array([0.0, -0.35, CARRY_Z + 0.05]), cmd_yaw, -1.0, p["speed"], hold=400)


PLANS0 = (
  settle0,  # 0
  above_lid,  # 1
  descend_lid,  # 2
  close,  # 3
  lift_lid,  # 4
  lid_aside,  # 5
  lower_lid,  # 6
  release,  # 7
  up,  # 8
  above_hammer,  # 9
  descend_hammer,  # 10
  close,  # 11
  lift_hammer,  # 12
  to_handover,  # 13
  hold_out,  # 14: until robot1 holds the handle
  let_go,  # 15
  rise,  # 16
  back0,  # 17
)
READY0 = tuple(_robot1_holds if i == 14 else always for i in range(len(PLANS0)))


def resume0(obs):
  """robot1 holding the hammer: let go (or, open already, rise and go back); holding it: hold it out,
  or carry it there, or lift it; holding the lid: lower it beside the bin, or carry it there, or lift
  it; the lid off the bin: go for the hammer; otherwise: go for the lid."""
  eef = obs["robot0_eef_pos"]
  holds = holding_hammer(obs, 0)
  centre, _ = _payload(obs)
  handover_phase = jnp.where(hammer_held_out(obs), 14, jnp.where(centre[2] > task.WALL_TOP + 0.03, 13, 12))
  handle = obs["object"][14:17]
  holds_lid = script.gripping(obs, handle, task.LID_HANDLE[0])
  lid_phase = jnp.where(
    script.near_xy(eef, jnp.asarray(LID_ASIDE), 0.04), 6, jnp.where(handle[2] > task.WALL_TOP + 0.06, 5, 4)
  )
  hammer_phase = jnp.where(script.near_xy(eef, _grasp_point(obs, -1.0, GRASP0), 0.012), 10, 9)
  lid_free = jnp.where(script.near_xy(eef, handle, 0.012), 2, 1)
  free = jnp.where(_lid_on_bin(obs), lid_free, jnp.where(_in_bin(centre, task.START_BIN), hammer_phase, 16))
  mine = jnp.where(holds, jnp.where(holding_hammer(obs, 1), 15, handover_phase), jnp.where(holds_lid, lid_phase, free))
  return jnp.where(~holds & holding_hammer(obs, 1), 16, mine)


# -- robot1: the trash, then the hammer from the handover to the target bin --------------------------
def params1(key):
  k = jax.random.split(key, 8)
  return dict(
    speed=uniform(k[0], 0.009, 0.014),
    settle=jax.random.randint(k[1], (), 2, 10),
    height=uniform(k[2], 0.06, 0.10),
    offset=uniform(k[3], -0.003, 0.003, (2,)),
    grasp_dz=uniform(k[4], -0.003, 0.003),
    close=jax.random.randint(k[5], (), 5, 10),
    drop=uniform(k[6], -0.03, 0.03, (2,)),
    place=uniform(k[7], -0.01, 0.01, (2,)),
  )


def above_trash(obs, p, cmd_pos, cmd_yaw):
  trash, yaw = obs["object"][7:10], script.quat_yaw_xyzw(obs["object"][10:14])
  pos = jnp.concatenate([trash[:2] + p["offset"], (task.WALL_TOP + p["height"])[None]])  # over the walls
  return target(pos, script.nearest_equivalent(yaw, cmd_yaw, jnp.pi / 2), -1.0, p["speed"], tol=0.015)


def descend_trash(obs, p, cmd_pos, cmd_yaw):
  pos = obs["object"][7:10] + jnp.concatenate([p["offset"], p["grasp_dz"][None]])
  return target(pos, cmd_yaw, -1.0, 0.6 * p["speed"], hold=1, tol=0.008)


def lift_trash(obs, p, cmd_pos, cmd_yaw):
  return target(cmd_pos.at[2].set(CARRY_Z), cmd_yaw, 1.0, p["speed"], tol=0.02)


def over_trash_bin(obs, p, cmd_pos, cmd_yaw):
  pos = jnp.concatenate([jnp.asarray(task.TRASH_BIN[:2]) + p["drop"], jnp.array([CARRY_Z])])
  return target(pos, cmd_yaw, 1.0, p["speed"], tol=0.02)


def lower_trash(obs, p, cmd_pos, cmd_yaw):
  return target(cmd_pos.at[2].set(DROP_Z), cmd_yaw, 1.0, 0.7 * p["speed"], tol=0.015)


def wait_above_handover(obs, p, cmd_pos, cmd_yaw):
  pos = jnp.asarray(HANDOVER) + jnp.array([0.0, GRASP1, 0.12])
  return target(pos, script.nearest_equivalent(jnp.array(0.0), cmd_yaw, jnp.pi), -1.0, p["speed"], tol=0.02)


def descend_handle(obs, p, cmd_pos, cmd_yaw):
  grasp = _grasp_point(obs, 1.0, GRASP1)
  pos = grasp + jnp.concatenate([p["offset"], p["grasp_dz"][None]])
  return target(pos, _across_handle(obs, cmd_yaw), -1.0, 0.5 * p["speed"], hold=1, tol=0.008)


def wait_release(obs, p, cmd_pos, cmd_yaw):
  return target(cmd_pos, cmd_yaw, 1.0, p["speed"], hold=2, tol=0.03)


def over_target_bin(obs, p, cmd_pos, cmd_yaw):
  """The hammer's centre over the target bin's, at carrying height."""
  centre, _ = _payload(obs)
  grip_from_centre = obs["robot1_eef_pos"] - centre
  xy = jnp.asarray(task.TARGET_BIN[:2]) + p["place"] + grip_from_centre[:2]
  return target(jnp.concatenate([xy, jnp.array([CARRY_Z])]), cmd_yaw, 1.0, p["speed"], tol=0.02)


def lower_hammer(obs, p, cmd_pos, cmd_yaw):
  return target(cmd_pos.at[2].set(DROP_Z), cmd_yaw, 1.0, 0.6 * p["speed"], tol=0.01)


def back1(obs, p, cmd_pos, cmd_yaw):
  return target(cmd_pos.at[2].set(CARRY_Z), cmd_yaw, -1.0, p["speed"], hold=400)


PLANS1 = (
  settle0,  # 0
  above_trash,  # 1
  descend_trash,  # 2
  close,  # 3
  lift_trash,  # 4
  over_trash_bin,  # 5
  lower_trash,  # 6
  release,  # 7
  up,  # 8
  wait_above_handover,  # 9: until the hammer is held out
  descend_handle,  # 10
  close,  # 11
  wait_release,  # 12: until robot0 has let go and risen
  over_target_bin,  # 13
  lower_hammer,  # 14
  release,  # 15
  back1,  # 16
)
READY1 = tuple({9: _held_out, 12: _robot0_open_and_clear}.get(i, always) for i in range(len(PLANS1)))


def resume1(obs):
  """Holding the hammer: wait for robot0 to let go, or lower it over the target bin, or carry it
  there; the hammer in the target bin: go back; the trash out of the target bin: wait for the hammer
  above the handover, or grasp it there; holding the trash: lower it over the trash bin, or carry it
  there, or lift it; otherwise: go for the trash."""
  eef, trash = obs["robot1_eef_pos"], obs["object"][7:10]
  centre, _ = _payload(obs)
  over_bin = script.near_xy(centre, jnp.asarray(task.TARGET_BIN), 0.03)
  carrying = jnp.where(holding_hammer(obs, 0), 12, jnp.where(over_bin, 14, 13))
  # Above the handle once the hammer is held out: go down for it (from the waiting point, 3.5 cm
  # along the handle from the grasp, as from anywhere nearer; a demonstrator resumed at every decision
  # must not send the hand back up before its descent is done).
  waiting = jnp.where(hammer_held_out(obs) & script.near_xy(eef, _grasp_point(obs, 1.0, GRASP1), 0.05), 10, 9)
  hammer_placed = _in_bin(centre, task.TARGET_BIN)
  after_trash = jnp.where(hammer_placed, 16, waiting)
  holds_trash = script.gripping(obs, trash, task.TRASH_HALF, robot=1)
  trash_phase = jnp.where(
    script.near_xy(eef, jnp.asarray(task.TRASH_BIN), 0.05), 6, jnp.where(trash[2] > task.WALL_TOP + 0.03, 5, 4)
  )
  trash_free = jnp.where(script.near_xy(eef, trash, 0.012), 2, 1)
  free = jnp.where(_in_bin(trash, task.TARGET_BIN), trash_free, after_trash)
  return jnp.where(holding_hammer(obs, 1), carrying, jnp.where(holds_trash, trash_phase, free))


EXPERT = script.BimanualExpert(
  arms=(
    script.ScriptedExpert(plans=PLANS0, sample_params=params0, resume=resume0, ready=READY0, robot=0),
    script.ScriptedExpert(plans=PLANS1, sample_params=params1, resume=resume1, ready=READY1, robot=1),
  )
)


# -- the varied demonstrator ------------------------------------------------------------------------
def varied0(key):
  k = jax.random.split(key, 4)
  return dict(params0(k[0]), **lift_expert.sample_styles(k[1]), **lift_expert.path_styles(k[2]),
              **lift_expert.path_styles(k[3], "hammer"))  # fmt: skip


def varied1(key):
  k = jax.random.split(key, 5)
  face = jax.random.randint(k[4], (), 0, 2).astype(jnp.float32)  # which pair of the trash cube's faces
  return dict(params1(k[0]), **lift_expert.sample_styles(k[1]), **lift_expert.path_styles(k[2]),
              **lift_expert.path_styles(k[3], "hammer"), face=face)  # fmt: skip


def above_trash_varied(obs, p, cmd_pos, cmd_yaw):
  """`above_trash` closing across either pair of the cube's faces (modulo a half turn, the fingers being
  alike, nearest the hand's yaw)."""
  t = above_trash(obs, p, cmd_pos, cmd_yaw)
  yaw = script.quat_yaw_xyzw(obs["object"][10:14]) + p["face"] * jnp.pi / 2
  return t._replace(yaw=script.nearest_equivalent(yaw, cmd_yaw, jnp.pi))


STYLED0 = {
  1: script.arced(above_lid, "side", "arc", "hover"),
  2: script.paced(descend_lid, "descend_speed"),
  5: script.arced(lid_aside, "carry_side", "carry_arc", "carry_hover"),
  9: script.arced(above_hammer, "hammer_side", "hammer_arc", "hammer_hover"),
  10: script.paced(descend_hammer, "descend_speed"),
}
STYLED1 = {
  1: script.arced(above_trash_varied, "side", "arc", "hover"),
  2: script.paced(descend_trash, "descend_speed"),
  5: script.arced(over_trash_bin, "carry_side", "carry_arc", "carry_hover"),
  13: script.arced(over_target_bin, "hammer_side", "hammer_arc", "hammer_hover"),
}
VARIED = script.BimanualExpert(
  arms=(
    script.ScriptedExpert(plans=tuple(STYLED0.get(i, f) for i, f in enumerate(PLANS0)), sample_params=varied0,
                          resume=resume0, ready=READY0, robot=0),
    script.ScriptedExpert(plans=tuple(STYLED1.get(i, f) for i, f in enumerate(PLANS1)), sample_params=varied1,
                          resume=resume1, ready=READY1, robot=1),
  )
)  # fmt: skip
