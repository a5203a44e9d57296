"""The LeRobot example (`examples/lerobot_robot.py`) drives a LeRobot robot through LeRobot's own `Robot`
interface with a served policy: LeRobot 0.4.4 and openpi-client 0.1.2 from PyPI in a virtual environment of
their own under $SOE_JAX_VENVS (default /work/venvs), made once; the test skips, saying why, where pip cannot
install them. torch comes from PyTorch's CPU wheels where that index answers, else from PyPI (its CUDA
wheels, which run on a CPU). openpi-client pins numpy < 2 and LeRobot 0.4.4's rerun-sdk needs numpy >= 2, so
pip cannot resolve the two together: openpi-client goes in after LeRobot without its dependencies, and its
other dependencies by name (it runs on numpy 2).

The robot is a stand-in for an SO-101 (`tests/robot/lerobot_scripted_arm/`: LeRobot's base classes,
registered as a plugin's robot, a kinematic arm and a camera). A scripted expert's demonstrations, taken
through its `send_action` and `get_observation`, are written as a LeRobotDataset with LeRobot's feature
names; a tiny policy reading the joints and the camera (at half the camera's height and width) is fitted
on them and served exploring in SOE mode and recording; the example runs two episodes, labelled on its
standard input (j, k), sending the camera as the robot gives it (the server brings it to the policy's
size). The robot got every action the server recorded as executed, from the observation recorded before
it, and saw the connection opened before and closed after them; the recording keeps the dataset's robot
type and feature names.
"""

import json
import os
import socket
import subprocess

import ml_collections
import numpy as np
import pytest

from soe_jax.data import lerobot
from soe_jax.robot import config as robot_config
from soe_jax.robot import run
from soe_jax.serve import modes as modes_lib
from tests import venvs
from tests.robot.test_sim_robot import Served

VERSION = "0.4.4"
PACKAGES = [f"lerobot=={VERSION}", "dm-tree", "msgpack", "websockets", "typing_extensions"]
NO_DEPS = ["openpi-client==0.1.2"]  # (its pin numpy<2 contradicts rerun-sdk's numpy>=2)
PROBE = (
  "import importlib.metadata as m, torch, lerobot.robots, openpi_client.websocket_client_policy; "
  f"assert m.version('lerobot') == {VERSION!r}"
)
CPU_WHEELS = "https://download.pytorch.org/whl/cpu"
HERE = os.path.dirname(os.path.abspath(__file__))
EXAMPLE = os.path.join(HERE, "..", "..", "examples", "lerobot_robot.py")
MOTORS = ("shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll", "gripper")
FPS, SECONDS = 10, 2.0  # the demonstrations' rate (the served control_hz) and each episode's length


def _pip_env() -> dict:
  """pip's environment: PyTorch's CPU wheels as an extra index where it answers."""
  env = dict(os.environ)
  try:
    socket.create_connection(("download.pytorch.org", 443), timeout=5).close()
    env["PIP_EXTRA_INDEX_URL"] = CPU_WHEELS
  except OSError:
    pass
  return env


def _run(python: str, args: list, tmp_path, **kwargs) -> subprocess.CompletedProcess:
  """`python args` with the scripted arm importable and LeRobot's calibration files under tmp_path."""
  env = dict(os.environ, PYTHONPATH=HERE, HF_LEROBOT_HOME=str(tmp_path / "lerobot_home"))
  r = subprocess.run([python, *args], capture_output=True, text=True, env=env, **kwargs)
  assert r.returncode == 0, r.stderr[-3000:]
  return r


@pytest.mark.slow
def test_the_example_drives_a_lerobot_robot(tmp_path):
  python = venvs.python("lerobot", PACKAGES, PROBE, env=_pip_env(), no_deps=NO_DEPS)
  demos = tmp_path / "demos.npz"
  script = "import sys, numpy as np, lerobot_scripted_arm as arm; np.savez(sys.argv[1], **arm.demonstrations(4, 30))"
  _run(python, ["-c", script, str(demos)], tmp_path, timeout=300)
  d = np.load(demos)
  episodes = [
    {"obs": {"observation.state": s, "observation.images.front": f}, "actions": a}
    for s, f, a in zip(d["state"], d["front"], d["action"])
  ]
  names = [f"{m}.pos" for m in MOTORS]
  lerobot.write_dataset(str(tmp_path / "data"), episodes, FPS, robot_type="scripted_arm",
                        names={"observation.state": names, "action": names})  # fmt: skip

  config = robot_config.config("smoke,image")
  config.policy.head = ml_collections.ConfigDict(dict(name="mlp", kwargs=dict(hidden=(32, 32))))  # (compiles fast)
  config.dataset.path = str(tmp_path / "data")
  config.dataset.image_size = (48, 64)  # the robot's camera is 96 x 128
  config.dataset.actions = ((("joints", 5), ("gripper", 1)),)  # an SO-101's joint positions, degrees
  workdir = str(tmp_path / "run")
  run.fit(config, workdir, progress=False)

  record, log = str(tmp_path / "recorded"), str(tmp_path / "robot.jsonl")
  server = Served(os.path.join(workdir, "rounds", "0", "ckpt"), f"--record={record}", "--mode=soe")
  try:
    args = [EXAMPLE, "--robot.discover_packages_path=lerobot_scripted_arm", "--robot.type=scripted_arm",
            "--robot.id=test", f"--robot.log={log}", f"--port={server.port}", f"--token={server.token}",
            "--episodes=2", f"--episode_time_s={SECONDS}", "--start_state=3"]  # fmt: skip
    out = _run(python, args, tmp_path, input="j\nk\n", timeout=600).stdout
  finally:
    server.close()

  calls = [json.loads(line) for line in open(log)]
  assert calls[0]["call"] == "connect" and calls[-1]["call"] == "disconnect"
  assert [c["call"] for c in calls].count("connect") == 1
  sent = [[c["action"][n] for n in names] for c in calls if c["call"] == "send_action"]
  seen = [c["state"] for c in calls if c["call"] == "get_observation"]
  steps = round(SECONDS * FPS)
  assert len(sent) == 2 * steps and len(seen) == 2 * (steps + 1)  # each episode: its start, then one per action
  assert out.count("'written': True") == 2, out

  info, recorded = lerobot.read_dataset(os.path.join(record, "lerobot"))
  assert info["robot_type"] == "scripted_arm"
  assert info["features"]["observation.state"]["names"] == names and info["features"]["action"]["names"] == names
  assert [ep["success"] for ep in recorded] == [True, False]  # j, k
  for i, ep in enumerate(recorded):
    np.testing.assert_allclose(ep["actions"], np.asarray(sent[i * steps : (i + 1) * steps], np.float32), atol=1e-5)
    states = seen[i * (steps + 1) : (i + 1) * (steps + 1) - 1]  # the observation each action was executed from
    np.testing.assert_allclose(ep["obs"]["observation.state"], np.asarray(states, np.float32), atol=1e-5)
    assert ep["obs"]["observation.images.front"].shape == (steps, 48, 64, 3)
    assert (ep["columns"]["mode"] == modes_lib.MODES.index("soe")).all() and (ep["columns"]["start_state"] == 3).all()
  # the served policy commands the arm: the joints it was sent are the policy's, not held still
  assert np.ptp(np.asarray(sent), axis=0).max() > 1.0


def test_the_example_imports_nothing_of_soe_jax():
  """The robot's environment has no JAX: the example reads the helper from its file, nothing else of soe_jax."""
  source = open(EXAMPLE).read()
  assert "import soe_jax" not in source and "from soe_jax" not in source
