"""The kept episodes measured: chunk-boundary steps of the commanded position, the object's tilt, the
grasps, pooled per method over seeds beside the demonstrations."""

import json

import numpy as np
import pytest

from configs import lift as lift_config
from soe_jax.analysis import results
from soe_jax.analysis.studies import kept
from soe_jax.data import hdf5
from soe_jax.experiment.rundir import RunDir
from soe_jax.runtime.errors import UserError


def _episode(steps_mm, tilt_deg, gripper):
  """Positions moving along x by `steps_mm` per step; the cube (lift's layout: pos, quat xyzw, rel)
  tilting about x to `tilt_deg` at the end; the gripper command per step."""
  t = len(gripper)
  actions = np.zeros((t, 10), np.float32)
  actions[:, 0] = np.concatenate([[0.0], np.cumsum(steps_mm)]) / 1000
  actions[:, -1] = gripper
  half = np.radians(np.linspace(0, tilt_deg, t)) / 2
  obj = np.zeros((t, 10), np.float32)
  obj[:, 3], obj[:, 6] = np.sin(half), np.cos(half)  # a rotation about x: x = sin, w = cos
  return {"actions": actions, "obs": {"object": obj}}


def test_an_episodes_steps_tilt_and_grasps():
  steps = [2.0] * 7 + [20.0] + [2.0] * 7 + [20.0] + [2.0] * 3  # t = 8 and 16 start new chunks
  grip = [-1] * 5 + [1] * 5 + [-1] * 5 + [1] * 5  # closes at t = 5 and t = 15
  m = kept.episode_measures(_episode(steps, 40.0, grip), 8, slice(3, 7))
  assert m["length"] == 20 and m["grasps"] == 2
  assert m["step_boundary_mm"] == pytest.approx(20.0, abs=1e-3) and m["step_inside_mm"] == pytest.approx(2.0, abs=1e-3)
  assert m["tilt_deg"] == pytest.approx(40.0, abs=1e-3)


def test_two_arm_episodes_average_steps_and_take_busier_grasps():
  """A two-arm episode averages the arms' steps and counts the busier gripper's grasps."""
  one = _episode([2.0] * 7 + [20.0] + [2.0] * 3, 0.0, [-1] * 6 + [1] * 6)  # robot0: grasps once
  other = _episode([4.0] * 11, 0.0, [-1, 1, -1, 1] * 3)  # robot1: grasps 6 times, steps 4 mm
  both = dict(one, actions=np.concatenate([one["actions"], other["actions"]], -1))
  m = kept.episode_measures(both, 8, slice(3, 7), num_robots=2)
  assert m["grasps"] == 6
  assert m["step_boundary_mm"] == pytest.approx(12.0, abs=1e-3) and m["step_inside_mm"] == pytest.approx(3.0, abs=1e-3)


def test_a_runs_kept_episodes_are_tabled_beside_its_demos(tmp_path):
  config = lift_config.get_config("smoke,soe")
  config.rounds.round0_dir = str(tmp_path / "round0")
  workdir = str(tmp_path / "soe")
  run = RunDir.create(workdir, config)
  smooth, jumpy = _episode([3.0] * 11, 5.0, [-1] * 6 + [1] * 6), _episode([3.0] * 7 + [30.0] + [3.0] * 3, 60.0,
                                                                          [-1, 1, -1, 1] * 3)  # fmt: skip
  hdf5.write_episodes(run.demos_path, [smooth, smooth], {})
  with pytest.raises(UserError, match="round 1 kept nothing or has not explored yet"):
    kept.run_measures(workdir, 1)
  hdf5.write_episodes(run.data_path(1), [jumpy, smooth], {})
  measured = kept.run_measures(workdir, 1)
  assert (measured["method"], measured["seed"], measured["kept"]["grasps"]) == ("soe", 0, [6, 1])
  study = tmp_path / "study"
  study.mkdir()
  record = dict(command="x", runs=[measured, dict(measured, seed=1)])
  kept.Kept().write(record, str(study / "lift.json"))  # a line per run, read back as written
  assert json.loads((study / "lift.json").read_text()) == dict(kind="kept", **record)
  lines = (study / "lift.json").read_text().splitlines()
  assert len(lines) == 7 and lines[4] == json.dumps(measured) + ","  # {, kind, command, "runs": [, a line per run, ]}
  rows = results.table(str(study)).splitlines()[2:]
  assert rows[0] == "| lift | demonstrations | 2 | 4 | 12.0 | 3.0 / 3.0 | 0 / 4 (0%) | 0 / 4 (0%) |"
  assert rows[1] == "| lift | soe | 2 | 4 | 12.0 | 16.5 / 3.0 | 2 / 4 (50%) | 2 / 4 (50%) |"
