"""A LeRobot robot driven by a policy that `python -m soe_jax serve` serves: the robot through LeRobot's own
`Robot` interface (`connect`, `get_observation`, `send_action`, `disconnect`), the episodes through the
robot-side helper (`soe_jax/serve/client.py`). It runs in the robot's environment (LeRobot and
openpi-client, no JAX) and imports nothing of soe_jax but the helper, loaded from its file: `client.py`
beside this script where it was copied, else the repository's.

  python examples/lerobot_robot.py --robot.type=so101_follower --robot.port=/dev/ttyACM0 --robot.id=arm \
      --robot.cameras="{front: {type: opencv, index_or_path: 0, width: 640, height: 480, fps: 30}}" \
      --host=127.0.0.1 --port=8000 --token=TOKEN --mode=soe --episodes=5 --episode_time_s=20 --start_state=0

The flags are LeRobot's (`lerobot-record`'s `--robot.*`, parsed by draccus); a robot of a plugin package
registers itself with `--robot.discover_packages_path=PACKAGE`. The robot talks to the policy as
`lerobot-record` writes a dataset: its float features, in order, are `observation.state`, each camera
`observation.images.<name>`, and each action is sent by the names of the `action` feature (the robot's
`action_features`, in order); so a policy fitted on what `lerobot-record` wrote with this robot reads and
commands it as the dataset did. Each action is held for one control period (the server's `control_hz`,
or `--fps`). After each episode a person labels it (j success, k failure, d discard), or on the server's
page with `--label=page`. `--start_state` names the start state the episodes are tries from (Pass@k).
"""

import importlib.util
import os
import time
from dataclasses import dataclass
from pathlib import Path

from lerobot.cameras.opencv.configuration_opencv import OpenCVCameraConfig  # noqa: F401  (--robot.cameras' type)
from lerobot.configs import parser
from lerobot.datasets.utils import build_dataset_frame, hw_to_dataset_features
from lerobot.robots import (  # noqa: F401  (the arms' modules register their configs)
  Robot,
  RobotConfig,
  koch_follower,
  make_robot_from_config,
  so_follower,
)
from lerobot.utils.import_utils import register_third_party_plugins
from lerobot.utils.robot_utils import precise_sleep

HELPER = "client.py"


@dataclass
class DriveConfig:
  robot: RobotConfig
  host: str = "127.0.0.1"
  port: int = 8000
  token: str | None = None  # the token `serve` printed (default: $SOE_JAX_SERVE_TOKEN)
  mode: str = "soe"  # base, soe, sime or steer
  episodes: int = 1
  episode_time_s: float = 20.0
  label: str = "keyboard"  # keyboard (j / k / d after each episode) or page (the server's page)
  start_state: int | None = None  # the start state the episodes are tries from, for Pass@k
  fps: float | None = None  # the control rate (None: the server's control_hz)


def load_helper():
  """The robot-side helper: `client.py` beside this script, else the repository's `soe_jax/serve/client.py`."""
  here = Path(__file__).resolve().parent
  for path in (here / HELPER, here.parent / "soe_jax" / "serve" / HELPER):
    if path.is_file():
      spec = importlib.util.spec_from_file_location("soe_jax_client", path)
      module = importlib.util.module_from_spec(spec)
      spec.loader.exec_module(module)
      return module
  raise FileNotFoundError(f"copy soe_jax/serve/{HELPER} beside {here / Path(__file__).name}")


class Arm:
  """The helper's `observe` and `act` over a LeRobot robot, laid out as `lerobot-record` records it."""

  def __init__(self, robot: Robot, fps: float):
    self.robot, self.period = robot, 1.0 / fps
    self.features = hw_to_dataset_features(robot.observation_features, "observation")
    self.names = hw_to_dataset_features(robot.action_features, "action")["action"]["names"]

  def check(self, metadata: dict) -> None:
    """Raises where the served policy reads a feature the robot lacks, or commands another number of actions."""
    missing = [k for k in metadata["spec"]["observations"] if k not in self.features]
    if missing:
      raise ValueError(f"the policy reads {', '.join(missing)}; {self.robot} has {', '.join(self.features)}")
    size = sum(n for arm in metadata["reply_actions"] for _, n in arm)
    if size != len(self.names):
      raise ValueError(f"the policy sends {size} numbers per action; {self.robot} takes {self.names}")

  def observe(self) -> dict:
    return build_dataset_frame(self.features, self.robot.get_observation(), "observation")

  def act(self, action) -> None:
    """Sends one action and returns a control period after it was sent."""
    start = time.perf_counter()
    self.robot.send_action({name: float(a) for name, a in zip(self.names, action)})
    precise_sleep(max(0.0, self.period - (time.perf_counter() - start)))


@parser.wrap()
def drive(cfg: DriveConfig) -> list[dict]:
  """Runs `cfg.episodes` episodes on the robot -> the server's `recorded` answer for each."""
  helper = load_helper()
  runner = helper.EpisodeRunner(cfg.host, cfg.port, api_key=cfg.token or os.environ.get("SOE_JAX_SERVE_TOKEN"))
  fps = cfg.fps or runner.metadata["control_hz"]
  robot = make_robot_from_config(cfg.robot)
  arm = Arm(robot, fps)
  arm.check(runner.metadata)
  label = {"keyboard": helper.keyboard_label, "page": None}[cfg.label]
  robot.connect()
  try:
    results = []
    for i in range(cfg.episodes):
      steps = max(1, round(cfg.episode_time_s * fps))
      results.append(runner.run_episode(arm.observe, arm.act, cfg.mode, steps, None, label, cfg.start_state))
      print(f"episode {i}: {results[-1]}", flush=True)
  finally:
    robot.disconnect()
  return results


def main() -> None:
  register_third_party_plugins()
  drive()


if __name__ == "__main__":
  main()
