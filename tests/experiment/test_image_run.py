"""An image policy through the whole experiment (`configs/lift.py:smoke,image`): the cameras' images in
the observation history, the buffer and the fit, kept episodes drawn from their states, the
checkpoint, and robomimic's image keys in the exported data; and the config checks that go with it."""

import h5py
import numpy as np
import pytest

from configs import lift as lift_config
from configs import transport as transport_config
from soe_jax.envs import manipulation, observations
from soe_jax.experiment import validation
from tests.render.test_render import needs_egl


def test_image_configs_are_checked_before_anything_runs():
  config = lift_config.get_config("smoke,image")
  assert validation.problems(config) == []
  config.env.obs_mode = "low_dim"
  assert any("set env.obs_mode='image'" in p for p in validation.problems(config))
  config.env.obs_mode = "rgb"
  assert validation.problems(config) == ["unknown env.obs_mode 'rgb'; known observation modes: low_dim, image"]
  config = lift_config.get_config("smoke,image")
  config.policy.encoder.kwargs.cameras = ("sideview_image",)
  config.policy.encoder.kwargs.crop_size = 90
  config.data.image_frames = 0
  found = "\n".join(validation.problems(config))
  assert (
    "unknown camera images 'sideview_image'; the lift task draws agentview_image, robot0_eye_in_hand_image" in found
  )
  assert "crop_size (90) must be in 1..env.image_size (84)" in found
  assert "data.image_frames must be at least 1" in found
  # Transport's image policy reads robomimic's four cameras of that task.
  config = transport_config.get_config("smoke,image")
  assert config.policy.encoder.kwargs.cameras == (
    "shouldercamera0_image",
    "shouldercamera1_image",
    "robot0_eye_in_hand_image",
    "robot1_eye_in_hand_image",
  )
  assert validation.problems(config) == []


@needs_egl
@pytest.mark.slow
def test_an_image_run_explores_keeps_refits_and_exports_images(tmp_path, expert_round):
  """An image smoke run (`lift:smoke,image`) explores, keeps, re-fits and exports images."""
  import jax

  from soe_jax.data import export
  from soe_jax.envs import registry as env_registry
  from soe_jax.policies import agent as agent_lib
  from soe_jax.train import checkpoint

  config = lift_config.get_config("smoke,image")
  config.env.episode_length = config.data.max_length = 150
  workdir, run, kept = expert_round(config)  # the re-fit drew the kept episodes' images from their states
  loaded = checkpoint.load(run.ckpt_dir(1))
  assert loaded.policy.image_keys == manipulation.IMAGE_KEYS
  env = env_registry.env_from_config(config.env)
  state = jax.jit(jax.vmap(env.reset))(jax.random.split(jax.random.PRNGKey(7), 1))
  hist = agent_lib.initial_history(observations.policy_input(state.obs, manipulation.IMAGE_KEYS), 2)
  actions = np.asarray(loaded.agent.act(hist, jax.random.PRNGKey(1)))  # the checkpoint acts on images
  assert actions.shape == (1, config.policy.n_action_steps, 10) and np.isfinite(actions).all()
  out = str(tmp_path / "data.hdf5")
  export.write(out, "robomimic", *run.fit_sets())
  with h5py.File(out) as f:
    demo = f["data/demo_5"]  # a kept episode (after the 4 demonstrations)
    for key in manipulation.IMAGE_KEYS:
      images = demo["obs"][key][()]
      assert images.dtype == np.uint8 and images.shape == (demo.attrs["num_samples"], 84, 84, 3)
    states = demo["states"][()]
  drawn = env.draw(states[:, 1 : 1 + env.mj_model.nq].astype(np.float32))  # as a step draws: from float32 qpos
  np.testing.assert_array_equal(images, drawn[manipulation.IMAGE_KEYS[-1]])
  env.renderer.close()


@needs_egl
@pytest.mark.slow
def test_soe_steer_steers_an_image_policy_along_its_latent(tmp_path):
  """The steering strategy on an image policy: the SNR over the round's data (its windows' images
  encoded), proposals along the chosen dimensions that differ in where they move the hand, and an
  exploration steered at every `every`-th decision."""
  import jax

  from soe_jax.data.episodes import EpisodeSet, build_buffer
  from soe_jax.experiment import loop
  from soe_jax.explore import registry as strategy_registry
  from soe_jax.policies import agent as agent_lib

  config = lift_config.get_config("smoke,image,soe_steer")
  settings = config.explore.strategy.kwargs
  settings.update(threshold_db=-1e9, max_dims=2, every=2)  # the two strongest dimensions, whatever their SNR
  with loop.opened(config, str(tmp_path / "run"), progress=False) as exp:
    demos, _, state = loop.round0(exp)
    buf = build_buffer(config, exp.policy, [EpisodeSet(demos, 0)], exp.env)
    rec, _, _ = exp.explore(state, 1, buf)
    snr, dims = rec["snr_db"], rec["steer_dims"]
    assert len(snr) == config.policy.bypass.latent_dim and np.isfinite(snr).all()
    assert sorted(dims) == sorted(np.argsort(snr)[-2:].tolist())
    assert 0 < rec["steered_fraction"] < 1  # every 2nd decision
    strategy = strategy_registry.make_strategy("soe_steer", exp.env, **settings)
    env_state = jax.vmap(exp.env.reset)(jax.random.split(jax.random.PRNGKey(3), 2))
    obs = observations.policy_input(env_state.obs, exp.policy.image_keys)
    hist = agent_lib.initial_history(obs, exp.policy.n_obs_steps)
    cands, dim_of = strategy.candidates(exp.agent(state), hist, jax.random.PRNGKey(4), tuple(dims))
  n = settings.num_choices
  assert cands.shape[:2] == (2, 2 * n) and dim_of.tolist() == [dims[0]] * n + [dims[1]] * n
  paths = np.asarray(observations.action_positions(cands, 1))  # (2, 2n, Ta, 1, 3)
  assert np.ptp(paths[:, :n], axis=1).max() > 1e-4  # the proposals along one dimension go different ways
