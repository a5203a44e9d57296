"""A robot's own rotation convention (`dataset.rotation`): a 7-d axis-angle arm whose rotations lie near
pi rad fits as rotation-6d with no action clipped, the server replies in axis-angle (the policy's own
chunk, converted), and a recording of its replies reads back with the policy's spec, as `refit` needs."""

import os

import ml_collections
import numpy as np
import pytest

from soe_jax import geometry
from soe_jax.data import lerobot, rotations
from soe_jax.data import spec as spec_lib
from soe_jax.policies import agent as agent_lib
from soe_jax.robot import config as robot_config
from soe_jax.robot import dataset as dataset_lib
from soe_jax.robot import run
from soe_jax.serve import session
from soe_jax.serve.modes import Modes
from soe_jax.train import checkpoint
from tests.robot.synthetic import AXIS_ANGLE_ARM, axis_angle_episodes

ROTVEC = dict(part="axis_angle", convention="rotvec", degrees=False)


@pytest.fixture(scope="module")
def fitted(tmp_path_factory):
  root = tmp_path_factory.mktemp("rotation")
  data = str(root / "demos")
  lerobot.write_dataset(data, axis_angle_episodes(np.random.default_rng(0)), fps=10)
  config = robot_config.config("smoke")
  config.policy.head = ml_collections.ConfigDict(dict(name="mlp", kwargs=dict(hidden=(32, 32))))  # (compiles fast)
  config.dataset.update(path=data, actions=(AXIS_ANGLE_ARM,))
  config.dataset.rotation.to_6d = True
  workdir = str(root / "run")
  record = run.fit(config, workdir, progress=False)
  return config, workdir, record


def test_an_axis_angle_arm_near_pi_fits_as_rotation_6d_with_no_action_clipped(fitted):
  config, workdir, record = fitted
  assert record["actions_clipped"] == 0.0
  spec = spec_lib.load(workdir)
  assert spec.actions == [[["position", 3], ["rotation_6d", 6], ["gripper", 1]]]
  assert spec.action_norm == [{"position": "range", "rotation_6d": "identity", "gripper": "range"}]
  assert spec.robot_rotations == [ROTVEC] and spec.robot_actions == [[list(p) for p in AXIS_ANGLE_ARM]]
  _, demos = dataset_lib.read(config.dataset.path, config.dataset)
  rotvec = np.concatenate([ep["actions"] for ep in axis_angle_episodes(np.random.default_rng(0))])[:, 3:6]
  np.testing.assert_allclose(np.concatenate([ep["actions"] for ep in demos])[:, 3:9],
                             rotations.to_6d(rotvec, ROTVEC), atol=1e-6)  # fmt: skip


def test_the_server_replies_in_axis_angle_and_its_recording_reads_back(fitted, tmp_path):
  config, workdir, _ = fitted
  loaded = checkpoint.load(os.path.join(workdir, "rounds", "0", "ckpt"))
  spec, agent = loaded.spec, loaded.agent
  conn = session.Session(agent, spec, keys=session.Keys(0, instance=0))
  ep = axis_angle_episodes(np.random.default_rng(1), 1, 16)[0]
  obs = {k: v[0] for k, v in ep["obs"].items()}
  reply = conn.infer(dict(obs, episode_start=True, timestamp=0.0))
  sent = reply["actions"]
  assert sent.shape == (loaded.policy.n_action_steps, 7) and sent.dtype == np.float32
  # The policy's own chunk for the same history and key, its rotation-6d orthonormalised.
  history = agent_lib.initial_history(session.policy_input(spec, obs), loaded.policy.n_obs_steps)
  chunk = np.asarray(Modes(agent, spec)("base", agent, history, session.request_key(0, 0, 0, 0)))[0]
  d6 = np.asarray(geometry.mat_to_rot6d(geometry.rot6d_to_mat(chunk[:, 3:9].astype(np.float64), xp=np), xp=np))
  np.testing.assert_allclose(rotations.to_6d(sent[:, 3:6], ROTVEC), d6, atol=1e-4)
  np.testing.assert_allclose(sent[:, [0, 1, 2, 6]], chunk[:, [0, 1, 2, 9]], atol=1e-5)
  assert session.metadata(spec, agent)["reply_actions"] == [list(map(list, AXIS_ANGLE_ARM))]
  # A recording holds the robot's 7-d actions; read with the run's config, it has the policy's spec.
  recorded = str(tmp_path / "recorded")
  lerobot.write_dataset(recorded, [dict(ep, actions=np.resize(sent, ep["actions"].shape).astype(np.float32))], fps=10)
  rec_spec, eps = dataset_lib.read(recorded, config.dataset)
  assert rec_spec.to_dict() == spec.to_dict() and eps[0]["actions"].shape == (16, 10)
