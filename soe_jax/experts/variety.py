"""How varied a batch of demonstrations is, read from what they commanded (`experts --measure`): the
approach (straight, or arced to the left or the right of the straight line to the grasp), which of
the object's symmetric equivalents the demonstrator chose (the pair of faces the fingers closed on; for
Square, whose handle is the nut's one grasp, whether the nut was turned the short way to square on its
way to the peg or to another square orientation), the spread of the hand's path length, how many hover or pause, and
the episodes' lengths; Transport's two arms each on their own (`ARMS`). The same numbers for scripted
and varied demonstrators, side by side, say whether the varied ones meet their thresholds (`THRESHOLDS`).
"""

from __future__ import annotations

import numpy as np

# An approach is arced when the hand passes this far (m) to one side of the straight line to the grasp.
ARC_MIN = 0.015
# A pause: at least this many consecutive steps with the gripper open and the commanded position moving
# less than PAUSE_SPEED (m per step), after the hand first moved.
PAUSE_STEPS = 8
PAUSE_SPEED = 0.0015  # (the commanded position carries the demonstrator's AR(1) wobble, ~0.5 mm a step)
# What varied demonstrations must show (issue: human-like demonstrators).
THRESHOLDS = dict(arc_each_side=0.25, equivalent_each=0.20, success=0.95)
# Each task's symmetric equivalents: "face" (which pair of faces the fingers close across) unless named
# here; "turn" (between the grasp and the release, whether the nut turned less than an eighth of a turn,
# the short way to square, or more, to another square orientation; the scripted Square demonstrator
# turns it the long way too where the short way would leave the handle pointing away from the robot).
EQUIVALENTS = {"square": "turn"}
# Two-arm tasks: each arm is measured on its own, from its 10 actions (from `first`) against the object of
# its first grasp (`pose`: its slice of `object`, position and xyzw quaternion), with its symmetric
# equivalents (None: the object has one grasp). Transport: robot0 takes the lid by its handle, a bar;
# robot1 the trash cube.
ARMS = {
  "transport": (
    dict(arm="robot0", first=0, pose=slice(14, 21), equivalents=None),
    dict(arm="robot1", first=10, pose=slice(7, 14), equivalents="face"),
  ),
}


def _yaw_of_rot6d(rot6d: np.ndarray) -> np.ndarray:
  """The yaw of the top-down frame's closing axis: rot6d's first column is that axis."""
  return np.arctan2(rot6d[..., 1], rot6d[..., 0])


def _quat_yaw(q: np.ndarray) -> np.ndarray:
  x, y, z, w = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
  return np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


def _side(path: np.ndarray) -> int:
  """Which side of the straight line from its first to its last point a horizontal path passes: +1 left
  of the direction of travel, -1 right, 0 within `ARC_MIN` of it (straight)."""
  d, rel = path[-1] - path[0], path - path[0]
  offset = (d[0] * rel[:, 1] - d[1] * rel[:, 0]) / max(np.linalg.norm(d), 1e-6)
  extreme = offset[np.argmax(np.abs(offset))]
  return 0 if abs(extreme) < ARC_MIN else int(np.sign(extreme))


def episode(actions: np.ndarray, object_pose: np.ndarray, face_period: float = np.pi / 2) -> dict:
  """One episode's (T, 10) commanded actions and (T, >= 7) object poses (position, xyzw quaternion) ->
  its approach side (-1 right, 0 straight, +1 left), its carry's (None without a release), the grasp's
  face (0 or 1: the closing axis along the object's yaw or a quarter turn from it), its turn (None
  without a release; 0 the object turned less than an eighth of a turn between grasp and release, 1
  more), path length, whether it paused, and its length."""
  pos, grip = actions[:, :3], actions[:, 9]
  closing = np.flatnonzero(grip > 0)
  t_close = int(closing[0]) if closing.size else len(actions) - 1
  released = np.flatnonzero(grip[t_close:] < 0)
  # The carry (Can's, Square's): from the grasp to the release, where the demonstration places the object.
  carry = _side(pos[t_close : t_close + released[0] + 1, :2]) if released.size else None
  turn = None
  if released.size:
    grasped, placed = _quat_yaw(object_pose[[t_close, t_close + released[0]], 3:7])
    turn = int(abs(np.angle(np.exp(1j * (placed - grasped)))) > np.pi / 4)
  rel_yaw = np.mod(_yaw_of_rot6d(actions[t_close, 3:9]) - _quat_yaw(object_pose[t_close, 3:7]), np.pi)
  face = int(np.round(rel_yaw / face_period)) % 2
  step = np.linalg.norm(np.diff(pos, axis=0), axis=1)
  moved = np.flatnonzero(step > PAUSE_SPEED)
  still = (step < PAUSE_SPEED) & (grip[1:] < 0)
  still[: moved[0] if moved.size else len(still)] = False  # before the hand first moved: settling
  runs = np.diff(np.concatenate([[0], still.astype(int), [0]]))
  longest = int((np.flatnonzero(runs == -1) - np.flatnonzero(runs == 1)).max()) if still.any() else 0
  return dict(
    side=_side(pos[: t_close + 1, :2]),
    carry=carry,
    face=face,
    turn=turn,
    path=float(step.sum()),
    paused=longest >= PAUSE_STEPS,
    length=len(actions),
  )


def measure(batch: dict, equivalents: str | None = "face", object_key: str = "object") -> dict:
  """A batch of demonstrations (`collect.run_demos`) -> the share of each approach side, each face,
  the same for the carry to the place (tasks that release the object), with `equivalents="turn"` the
  share of each turn (with None neither: the object has one grasp), the path length's coefficient of
  variation, the share that paused, length mean and std (over the successful episodes), the success
  rate, and which `THRESHOLDS` hold (the equivalents' on the faces or the turns)."""
  ok = np.flatnonzero(batch["success"])
  eps = [episode(batch["actions"][i, : batch["length"][i]], batch["obs"][object_key][i, : batch["length"][i]])
         for i in ok]  # fmt: skip
  if not eps:
    return dict(success_rate=float(np.mean(batch["success"])), episodes=0)
  share = lambda key, value: float(np.mean([e[key] == value for e in eps]))
  paths, lengths = np.array([e["path"] for e in eps]), np.array([e["length"] for e in eps])
  out = dict(
    episodes=len(eps),
    success_rate=float(np.mean(batch["success"])),
    arc_left=share("side", 1),
    arc_right=share("side", -1),
    straight=share("side", 0),
    **({} if eps[0]["carry"] is None else dict(carry_left=share("carry", 1), carry_right=share("carry", -1))),
    **({} if equivalents is None else dict(face_0=share("face", 0), face_1=share("face", 1))),
    **(dict(turn_short=share("turn", 0), turn_long=share("turn", 1)) if equivalents == "turn" else {}),
    path_cv=float(paths.std() / paths.mean()),
    paused=float(np.mean([e["paused"] for e in eps])),
    length_mean=float(lengths.mean()),
    length_std=float(lengths.std()),
  )
  met = out["thresholds_met"] = dict(
    arc_each_side=min(out["arc_left"], out["arc_right"]) >= THRESHOLDS["arc_each_side"]
  )
  if equivalents is not None:
    shares = ("face_0", "face_1") if equivalents == "face" else ("turn_short", "turn_long")
    met[f"{equivalents}_each"] = min(out[k] for k in shares) >= THRESHOLDS["equivalent_each"]
  met["success"] = out["success_rate"] >= THRESHOLDS["success"]
  if "carry_left" in out:
    met["carry_each_side"] = min(out["carry_left"], out["carry_right"]) >= THRESHOLDS["arc_each_side"]
  return out


def measure_task(batch: dict, task: str) -> dict:
  """`measure` with `task`'s equivalents; a two-arm task's (`ARMS`) per arm, under `arms`, beside the
  episodes' success rate and every arm's thresholds, each named after its arm."""
  if task not in ARMS:
    return measure(batch, EQUIVALENTS.get(task, "face"))
  arms = {}
  for a in ARMS[task]:
    one = dict(batch, actions=batch["actions"][..., a["first"] : a["first"] + 10],
               obs=dict(object=batch["obs"]["object"][..., a["pose"]]))  # fmt: skip
    arms[a["arm"]] = measure(one, a["equivalents"])
  met = {f"{arm}_{k}": ok for arm, m in arms.items() for k, ok in m.get("thresholds_met", {}).items()}
  return dict(arms=arms, success_rate=float(np.mean(batch["success"])), thresholds_met=met)
