"""A robot's policy on files alone, in a process where importing `soe_jax.envs` raises (`synthetic.py`):
LeRobotDataset demonstrations -> fit -> served with the token -> recorded episodes with success labels
-> refit on exactly the successful ones -> re-served chunk equal to the checkpoint's in-process chunk."""

import json
import subprocess
import sys

import pytest


def _run(tmp_path, *flags):
  done = subprocess.run([sys.executable, "-m", "tests.robot.synthetic", str(tmp_path), *flags],
                        capture_output=True, text=True, timeout=600)  # fmt: skip
  assert done.returncode == 0, done.stderr[-3000:]
  return json.loads(done.stdout.strip().splitlines()[-1])


def _check(out):
  assert out["fit0"] == {"0": 4}  # the demonstrations
  assert out["fit1"] == {"0": 4, "1": sum(out["labels"])}  # and exactly the episodes labelled successful
  assert out["served0"] < 1e-6 and out["served1"] < 1e-6  # the wire's chunk is the in-process one
  assert out["control_hz"] == 10.0 and out["gripper_scale"] > 5  # a gripper in metres, normalised by range
  assert not out["envs_imported"]


def test_a_synthetic_robot_fits_serves_and_refits_without_the_simulator(tmp_path):
  _check(_run(tmp_path))


@pytest.mark.slow
def test_the_same_with_a_96_by_128_camera(tmp_path):
  _check(_run(tmp_path, "--image"))
