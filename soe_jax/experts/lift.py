"""Lift demonstrators: over the cube, down, close, lift. `EXPERT` is the scripted one (one path, per-episode
speed, offsets and yaw jitter); `VARIED` adds human-like styles drawn per episode: the approach straight
or arced to either side, the grasp on either pair of the cube's faces, the descent's own speed, and
an occasional hover over the cube before going down."""

from __future__ import annotations

import jax
import jax.numpy as jnp

from soe_jax.envs import lift as lift_task
from soe_jax.experts import script
from soe_jax.experts.script import target, uniform


def sample_params(key):
  k = jax.random.split(key, 7)
  return dict(
    speed=uniform(k[0], 0.009, 0.016),
    settle=jax.random.randint(k[1], (), 2, 8),
    height=uniform(k[2], 0.05, 0.10),
    offset=uniform(k[3], -0.004, 0.004, (2,)),
    grasp_dz=uniform(k[4], -0.004, 0.004),
    close=jax.random.randint(k[5], (), 5, 10),
    yaw=uniform(k[6], -0.12, 0.12),
  )


def _cube(obs):
  return obs["object"][:3], script.quat_yaw_xyzw(obs["object"][3:7])


def _grasp_yaw(obs, p, cmd_yaw):
  _, yaw = _cube(obs)
  return script.nearest_equivalent(yaw + p["yaw"], cmd_yaw, jnp.pi / 2)


# The varied demonstrator's styles: the share of approaches arced to each side (the rest straight), the
# sideways size of an arc, the share of episodes that hover over the cube, and for how long.
ARC_SHARE = 1 / 3
ARC_SIZE = (0.03, 0.08)
HOVER_SHARE = 0.3
HOVER_STEPS = (8, 20)


def sample_styles(key) -> dict:
  """A varied demonstrator's styles for one episode (Lift's, and the approach and carry of Can's and
  Square's): the approach's side (-1, 0, +1) and arc size, the speed and the descent's, and a hover."""
  k = jax.random.split(key, 6)
  speed = uniform(k[0], 0.007, 0.018)
  side = jax.random.choice(k[1], jnp.array([-1.0, 0.0, 1.0]), p=jnp.array([ARC_SHARE, 1 - 2 * ARC_SHARE, ARC_SHARE]))
  hover = jax.random.uniform(k[2]) < HOVER_SHARE
  return dict(
    speed=speed,
    descend_speed=speed * uniform(k[3], 0.35, 0.9),
    side=side,
    arc=uniform(k[4], *ARC_SIZE),
    hover=jnp.where(hover, jax.random.randint(k[5], (), *HOVER_STEPS), 0),
  )


def path_styles(key, path: str = "carry") -> dict:
  """`sample_styles`' arc and hover for another path of the episode, each drawn anew and named after it:
  `carry_side`, `carry_arc`, `carry_hover` for the carry to the place (Can's, Square's)."""
  styles = sample_styles(key)
  return {f"{path}_{k}": styles[k] for k in ("side", "arc", "hover")}


def styled_pick_and_place(settle, above, descend, close, lift, carry, *place) -> tuple:
  """A varied pick-and-place demonstrator's plans (Can's, Square's) from its scripted ones: the approach
  and the carry arced and hovering by `sample_styles`' and `path_styles`' parameters, the descent at
  its own pace; the other phases as they are."""
  return (
    settle,
    script.arced(above, "side", "arc", "hover"),
    script.paced(descend, "descend_speed"),
    close,
    lift,
    script.arced(carry, "carry_side", "carry_arc", "carry_hover"),
    *place,
  )


def sample_varied_params(key):
  k = jax.random.split(key, 3)
  face = jax.random.randint(k[2], (), 0, 2).astype(jnp.float32)  # which pair of faces the fingers close on
  return dict(sample_params(k[0]), **sample_styles(k[1]), face=face)


def above_varied(obs, p, cmd_pos, cmd_yaw):
  cube, yaw = _cube(obs)
  pos = cube + jnp.concatenate([p["offset"], p["height"][None]])
  # The fingers close across either pair of faces: the cube's yaw or a quarter turn from it, each taken
  # modulo a half turn (the two fingers are alike) nearest the hand's yaw.
  grasp = script.nearest_equivalent(yaw + p["yaw"] + p["face"] * jnp.pi / 2, cmd_yaw, jnp.pi)
  bend = script.arc(cmd_pos, pos, p["side"], p["arc"])
  return target(pos, grasp, -1.0, p["speed"], hold=p["hover"], tol=0.015, bend=bend)


def descend_varied(obs, p, cmd_pos, cmd_yaw):
  cube, _ = _cube(obs)
  pos = cube + jnp.concatenate([p["offset"], p["grasp_dz"][None]])
  return target(pos, cmd_yaw, -1.0, p["descend_speed"], hold=1, tol=0.008)


def settle(obs, p, cmd_pos, cmd_yaw):
  return target(cmd_pos, cmd_yaw, -1.0, p["speed"], hold=p["settle"])


def above(obs, p, cmd_pos, cmd_yaw):
  cube, _ = _cube(obs)
  pos = cube + jnp.concatenate([p["offset"], p["height"][None]])
  return target(pos, _grasp_yaw(obs, p, cmd_yaw), -1.0, p["speed"], tol=0.015)


def descend(obs, p, cmd_pos, cmd_yaw):
  cube, _ = _cube(obs)
  pos = cube + jnp.concatenate([p["offset"], p["grasp_dz"][None]])
  return target(pos, cmd_yaw, -1.0, 0.6 * p["speed"], hold=1, tol=0.008)


def close(obs, p, cmd_pos, cmd_yaw):
  return target(cmd_pos, cmd_yaw, 1.0, p["speed"], hold=p["close"], tol=0.02)


def lift(obs, p, cmd_pos, cmd_yaw):
  return target(cmd_pos + jnp.array([0.0, 0.0, 0.12]), cmd_yaw, 1.0, p["speed"], hold=40, tol=0.02)


def resume(obs):
  """Holding the cube: lift; over it: descend; otherwise: go over it."""
  cube, _ = _cube(obs)
  over = script.near_xy(obs["robot0_eef_pos"], cube, 0.012)
  return jnp.where(script.gripping(obs, cube, lift_task.CUBE_HALF), 4, jnp.where(over, 2, 1))


EXPERT = script.ScriptedExpert(plans=(settle, above, descend, close, lift), sample_params=sample_params, resume=resume)
VARIED = script.ScriptedExpert(plans=(settle, above_varied, descend_varied, close, lift),
                               sample_params=sample_varied_params, resume=resume)  # fmt: skip
