"""A LeRobot robot that stands in for an SO-101 arm in tests: LeRobot's own `Robot` and `RobotConfig` base
classes, registered as LeRobot registers a plugin's robot (`--robot.type=scripted_arm` once
`--robot.discover_packages_path=lerobot_scripted_arm` has imported this module), with the SO-101's motor
features (`shoulder_pan.pos`, ..., `gripper.pos`, degrees and a 0-100 gripper) and one camera.

The arm is kinematic: each `send_action` moves every joint half-way to its goal, at once. The camera sees
it from above: a white square where the shoulder's pan and lift put the hand, its red channel the
gripper's opening. Every call is appended to `--robot.log` as a JSON line (connect, observation, action,
disconnect). A package, as LeRobot's plugin loader imports one. Needs LeRobot; runs in its environment,
not this project's. `demonstrations` are a scripted expert's, taken through the same interface.
"""

from __future__ import annotations

import json
from dataclasses import dataclass

import numpy as np
from lerobot.robots import Robot, RobotConfig

MOTORS = ("shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll", "gripper")
GOAL = np.array([20.0, -30.0, 45.0, 60.0, 0.0, 10.0])  # where the expert takes the arm (degrees; gripper 0-100)
GAIN = 0.5  # the fraction of the way to its goal a joint moves per action
CAMERA = (96, 128)  # height, width


@RobotConfig.register_subclass("scripted_arm")
@dataclass
class ScriptedArmConfig(RobotConfig):
  seed: int = 0  # draws the pose the arm starts in
  log: str | None = None  # a file each call is appended to as a JSON line


class ScriptedArm(Robot):
  """An SO-101's features over a kinematic arm and a rendered camera."""

  config_class = ScriptedArmConfig
  name = "scripted_arm"

  def __init__(self, config: ScriptedArmConfig):
    super().__init__(config)
    self.config = config
    self.q = np.random.default_rng(config.seed).uniform(-40.0, 40.0, len(MOTORS))
    self.q[-1] = 50.0
    self.connected = False

  @property
  def observation_features(self) -> dict:
    return {**{f"{m}.pos": float for m in MOTORS}, "front": (*CAMERA, 3)}

  @property
  def action_features(self) -> dict:
    return {f"{m}.pos": float for m in MOTORS}

  @property
  def is_connected(self) -> bool:
    return self.connected

  def connect(self, calibrate: bool = True) -> None:
    self.connected = True
    self._log(dict(call="connect"))

  @property
  def is_calibrated(self) -> bool:
    return True

  def calibrate(self) -> None:
    pass

  def configure(self) -> None:
    pass

  def get_observation(self) -> dict:
    assert self.connected, "get_observation before connect"
    state = [float(v) for v in self.q]
    self._log(dict(call="get_observation", state=state))
    return {**{f"{m}.pos": v for m, v in zip(MOTORS, state)}, "front": render(self.q)}

  def send_action(self, action: dict) -> dict:
    assert self.connected, "send_action before connect"
    assert set(action) == set(self.action_features), sorted(action)
    goal = np.array([action[f"{m}.pos"] for m in MOTORS])
    self.q = self.q + GAIN * (goal - self.q)
    self._log(dict(call="send_action", action=action))
    return action

  def disconnect(self) -> None:
    self.connected = False
    self._log(dict(call="disconnect"))

  def _log(self, entry: dict) -> None:
    if self.config.log:
      with open(self.config.log, "a") as f:
        f.write(json.dumps(entry) + "\n")


def render(q: np.ndarray) -> np.ndarray:
  """The camera's (H, W, 3) uint8 view from above: a 12-pixel white square where the pan (across) and the
  lift (down) put the hand, its red channel the gripper's opening, on grey."""
  img = np.full((*CAMERA, 3), 60, np.uint8)
  row = int(np.clip((q[1] + 60.0) / 120.0, 0, 1) * (CAMERA[0] - 12))
  col = int(np.clip((q[0] + 60.0) / 120.0, 0, 1) * (CAMERA[1] - 12))
  img[row : row + 12, col : col + 12] = (int(np.clip(q[-1], 0, 100) * 2.55), 255, 255)
  return img


def demonstrations(episodes: int, steps: int) -> dict:
  """A scripted expert through LeRobot's interface: from each start, actions a bounded step towards GOAL
  -> {"state": (E, T, 6), "front": (E, T, H, W, 3), "action": (E, T, 6)}, as `lerobot-record` lays them out."""
  out = {"state": [], "front": [], "action": []}
  for seed in range(episodes):
    robot = ScriptedArm(ScriptedArmConfig(id="demo", seed=seed))
    robot.connect()
    for key in out:
      out[key].append([])
    for _ in range(steps):
      obs = robot.get_observation()
      state = np.array([obs[f"{m}.pos"] for m in MOTORS])
      action = state + np.clip(GOAL - state, -8.0, 8.0) / GAIN
      robot.send_action({f"{m}.pos": float(a) for m, a in zip(MOTORS, action)})
      out["state"][-1].append(state)
      out["front"][-1].append(obs["front"])
      out["action"][-1].append(action)
    robot.disconnect()
  return {k: np.asarray(v, np.uint8 if k == "front" else np.float32) for k, v in out.items()}
