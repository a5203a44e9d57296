"""Every action part has a normaliser: a 7-d axis-angle arm whose rotations lie near pi rad fits with no
action clipped (the rotation normalised by its range in the data, `dataset.normalize.axis_angle`), and a
part left as it is that the data overflows is named, part and dimension, in the clipping warning."""

import json
import logging
import os

import ml_collections
import numpy as np
import pytest

from soe_jax.data import lerobot
from soe_jax.data.episodes import EpisodeSet
from soe_jax.policies.policy import policy_from_spec
from soe_jax.robot import config as robot_config
from soe_jax.robot import dataset as dataset_lib
from soe_jax.robot import run
from soe_jax.runtime.errors import UserError
from soe_jax.train import action_box, checkpoint, normalization
from tests.robot.synthetic import AXIS_ANGLE_ARM, axis_angle_episodes


@pytest.fixture(scope="module")
def data(tmp_path_factory):
  root = str(tmp_path_factory.mktemp("axis_angle") / "demos")
  lerobot.write_dataset(root, axis_angle_episodes(np.random.default_rng(0)), fps=10)
  return root


def _config(data: str) -> ml_collections.ConfigDict:
  config = robot_config.config("smoke")
  config.policy.head = ml_collections.ConfigDict(dict(name="mlp", kwargs=dict(hidden=(32, 32))))  # (compiles fast)
  config.dataset.update(path=data, actions=(AXIS_ANGLE_ARM,))
  return config


def test_an_axis_angle_arm_near_pi_fits_with_no_action_clipped(data, tmp_path):
  workdir = str(tmp_path / "run")
  record = run.fit(_config(data), workdir, progress=False)
  assert record["actions_clipped"] == 0.0
  spec = json.load(open(os.path.join(workdir, "spec.json")))
  assert spec["action_norm"] == [{"position": "range", "axis_angle": "range", "gripper": "range"}]
  norm = checkpoint.load(os.path.join(workdir, "rounds", "0", "ckpt")).state.normalizer
  actions = np.concatenate([ep["actions"] for ep in axis_angle_episodes(np.random.default_rng(0))])
  scaled = np.asarray(norm.normalize_actions(actions))
  assert np.abs(actions[:, 3]).max() > 3.0 and np.abs(actions * norm.act_scale + norm.act_offset).max() <= 1.0
  # What the policy can command reaches the data's rotations: pi rad, not 1 rad.
  np.testing.assert_allclose(np.asarray(norm.unnormalize_actions(scaled)), actions, atol=1e-5)


def test_a_part_left_as_it_is_and_overflowing_is_named_in_the_warning(data, caplog):
  config = _config(data)
  config.dataset.normalize.axis_angle = "identity"
  spec, demos = dataset_lib.read(data, config.dataset)
  policy = policy_from_spec(config.policy, spec)
  norm = normalization.fit_normalizer(policy, spec, demos, "demonstrations", 0.1)
  with caplog.at_level(logging.WARNING):
    clipped = action_box.check([EpisodeSet(demos, 0)], norm, spec, "demonstrations", str)
  assert clipped == 1.0
  assert "robot0 axis_angle[0]" in caplog.text and "dataset.normalize.axis_angle" in caplog.text
  assert "robot0 position" not in caplog.text and "robot0 gripper" not in caplog.text


def test_a_run_saved_before_per_part_fields_keeps_its_spec():
  """A workdir's config.json from before `dataset.normalize` names the gripper's rule alone: `refit`
  reads the same spec from it as `fit` saved."""
  old = ml_collections.ConfigDict(dict(gripper="identity"))
  assert dataset_lib.action_norm(old, [list(robot_config.ARM)]) == [{"gripper": "identity"}]
  both = robot_config.config("smoke").dataset
  both.gripper = "identity"
  with pytest.raises(UserError, match="dataset.gripper is now dataset.normalize.gripper"):
    dataset_lib.action_norm(both, [list(robot_config.ARM)])
