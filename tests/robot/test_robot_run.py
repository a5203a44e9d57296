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


def test_bad_robot_inputs_are_one_line_and_write_nothing(tmp_path, capsys):
  """A dataset missing a key the config names, an action layout that does not fit, a missing dataset:
  one `error:` line, exit status 2, no workdir written."""
  import numpy as np

  from soe_jax import __main__ as entry
  from soe_jax.data import lerobot
  from tests.robot import synthetic

  data = str(tmp_path / "demos")
  lerobot.write_dataset(data, synthetic.episodes(np.random.default_rng(0), 2, 12, False), fps=10)
  base = ["soe_jax", "fit", "--config=configs/robot.py:smoke", f"--workdir={tmp_path / 'run'}"]
  for extra, message in [
    ([f"--config.dataset.path={data}", "--config.dataset.observations=('observation.wrist',)"],
     "no feature observation.wrist; its features:"),
    ([f"--config.dataset.path={data}", "--config.dataset.actions=((('position', 3), ('gripper', 1)),)"],
     "the action feature has 10 numbers, dataset.actions lays out 4"),
    ([f"--config.dataset.path={tmp_path / 'nowhere'}"], "is not a directory"),
  ]:  # fmt: skip
    with pytest.raises(SystemExit) as e:  # (in this process: a command line's process start is seconds)
      entry.main(base + extra)
    err = capsys.readouterr().err
    assert e.value.code == 2 and err.startswith("error: ") and message in err, err
    assert err.count("\n") == 1, err
  assert not (tmp_path / "run").exists()


def test_a_camera_under_a_preset_that_reads_none_names_the_preset_to_use(tmp_path, capsys):
  """A camera the preset's policy does not read: one line naming the preset that reads it."""
  import numpy as np

  from soe_jax import __main__ as entry
  from soe_jax.data import lerobot
  from tests.robot import synthetic

  data = str(tmp_path / "demos")
  lerobot.write_dataset(data, synthetic.episodes(np.random.default_rng(0), 1, 8, True), fps=10)
  with pytest.raises(SystemExit) as e:
    entry.main(["soe_jax", "fit", "--config=configs/robot.py:cpu", f"--config.dataset.path={data}",
                f"--workdir={tmp_path / 'run'}"])  # fmt: skip
  err = capsys.readouterr().err
  assert e.value.code == 2 and err.count("\n") == 1, err
  assert "has cameras (observation.images.wrist)" in err and "configs/robot.py:cpu,image" in err, err
  assert not (tmp_path / "run").exists()
