"""Exploration strategies: SIME's schedule and noise, SOE's alpha, steering candidates, the registry."""

import dataclasses

import jax
import jax.numpy as jnp
import ml_collections
import numpy as np
import pytest

from soe_jax.explore import registry, sime, steer, steering
from soe_jax.policies import normalizer as normalizer_lib
from soe_jax.policies.agent import Agent
from soe_jax.policies.policy import make_policy

OBS_DIM, ACTION_DIM = 5, 10


def _policy(sampler="ddim", steps=10):
  kwargs = dict(down_dims=(16, 32, 64), step_embed_dim=32, sampler=sampler, num_inference_steps=steps)
  config = ml_collections.ConfigDict(
    dict(
      head=dict(name="diffusion_unet", kwargs=kwargs),
      encoder=dict(name="lowdim", kwargs={}),
      bypass=dict(enabled=True, latent_dim=4, hidden=32, beta=1e-3),
      n_obs_steps=2,
      horizon=16,
      n_action_steps=8,
    )
  )
  return make_policy(config, OBS_DIM, ACTION_DIM)


def _agent(policy, obs_span=2.0):
  rng = np.random.default_rng(0)
  obs = rng.uniform(0, obs_span, (200, OBS_DIM)) * np.arange(1, OBS_DIM + 1)  # a different range per dim
  actions = rng.uniform(-1, 1, (200, ACTION_DIM))
  return Agent(policy, policy.init(jax.random.PRNGKey(0)), normalizer_lib.fit(obs, actions, margin=0.0))


def test_sime_schedule_matches_the_spec():
  # specs/sime_baseline.md: DDIM-20 over 100 training steps visits k = 95, 90, ..., 0; u = 1 - k/100;
  # with tau1 = 0, tau2 = 1 the noise std is s * u: s*0.05, s*0.10, ..., s*1.0 (largest at the end).
  policy = _policy(steps=20)
  u = jnp.stack([policy.head.progress(i) for i in range(20)])
  np.testing.assert_allclose(u, np.arange(1, 21) * 0.05, atol=1e-6)
  std = sime.noise_std(u, 0.01)
  np.testing.assert_allclose(np.asarray(std)[[0, 1, 9, 19]], [0.0005, 0.001, 0.005, 0.01], atol=1e-7)
  # The general CADS ramp: 1 below tau1, 0 above tau2, linear in between.
  g = sime.gamma(jnp.array([0.1, 0.2, 0.5, 0.8, 0.9]), tau1=0.2, tau2=0.8)
  np.testing.assert_allclose(g, [1.0, 1.0, 0.5, 0.0, 0.0], atol=1e-6)
  # DDPM visits every timestep 99 .. 0.
  ddpm = _policy(sampler="ddpm")
  np.testing.assert_allclose([ddpm.head.progress(0), ddpm.head.progress(99)], [0.01, 1.0], atol=1e-6)


def test_sime_noise_is_raw_scale_converted_per_dimension():
  policy = _policy()
  agent = _agent(policy)
  cond_fn = sime.cond_fn(policy, agent.normalizer, scale=0.01)
  cond = jnp.zeros((20000, policy.cond_dim))
  for i in (0, 4, 9):
    noise = cond_fn(cond, i, jax.random.PRNGKey(i))
    u = float(policy.head.progress(i))
    expected = 0.01 * u * np.tile(np.asarray(agent.normalizer.obs_scale), 2)
    np.testing.assert_allclose(noise.std(0), expected, rtol=0.05)
  # Fresh noise at every call: two calls with different keys differ.
  assert not np.allclose(cond_fn(cond[:2], 3, jax.random.PRNGKey(1)), cond_fn(cond[:2], 3, jax.random.PRNGKey(2)))


def test_sime_on_images_puts_one_scale_on_the_whole_conditioning():
  """SIME on an image policy puts one scale on the whole conditioning."""
  from configs import lift
  from soe_jax.experiment import task

  config = lift.get_config("smoke,image,sime")
  assert config.explore.strategy.kwargs.scale == 0.5  # SIME's scale for image tasks
  policy = task.policy(config)
  assert policy.image_keys == ("agentview_image", "robot0_eye_in_hand_image")
  assert policy.cond_dim == 2 * (2 * 64 + policy.obs_dim)  # per frame: 64 features per camera, then the vector
  norm = _agent(_policy()).normalizer  # (its scales play no part here)
  fn = sime.cond_fn(policy, norm, scale=0.5)
  noise = fn(jnp.zeros((20000, policy.cond_dim)), 9, jax.random.PRNGKey(0))  # the last DDIM-10 call: u = 1
  np.testing.assert_allclose(noise.std(0), np.full(policy.cond_dim, 0.5), rtol=0.05)


@pytest.mark.slow
def test_soe_alpha_zero_is_the_mean_path_and_alpha_spreads():
  policy = _policy()
  agent = _agent(policy)
  obs = jax.random.uniform(jax.random.PRNGKey(3), (16, 2, OBS_DIM), minval=0, maxval=2)
  key = jax.random.PRNGKey(4)

  def chunk(alpha):
    return registry.make_strategy("soe", alpha=alpha)(agent, obs, None, key)

  zero, aux = chunk(0.0)
  # alpha = 0: the chunk of the exploration path's mean, z = mu, decoded with the same head noise.
  obs_n = agent.normalizer.normalize_obs(obs)
  mu, _ = policy.latent(agent.params, policy.encode(agent.params, obs_n))
  _, key_head = jax.random.split(key)
  mean_actions, _ = policy.head.sample(agent.params["head"], policy.decode_latent(agent.params, mu), key_head)
  expected = agent.executed(agent.normalizer.unnormalize_actions(mean_actions))
  np.testing.assert_allclose(zero, expected, atol=1e-5)
  np.testing.assert_allclose(aux["z"], mu, atol=1e-6)
  # Larger alpha: further from the mean path, with the same keys.
  spread = [float(jnp.mean(jnp.abs(chunk(a)[0] - zero))) for a in (0.5, 2.0, 8.0)]
  assert 0 < spread[0] < spread[1] < spread[2]


@pytest.mark.slow
def test_soe_hold_keeps_the_latent_noise_for_that_many_decisions():
  policy = _policy()
  agent = _agent(policy)
  obs = jax.random.uniform(jax.random.PRNGKey(3), (4, 2, OBS_DIM), minval=0, maxval=2)
  slice_key = jax.random.PRNGKey(5)
  state = lambda step: type("S", (), {"info": {"steps": jnp.full(4, step), "slice_key": jnp.stack([slice_key] * 4)}})()
  mu, log_std = agent.latent(obs)

  def noise(strategy, decision):  # eps = (z - mu) / (alpha sigma), with the rollout's key of that decision
    _, aux = strategy(agent, obs, state(8 * decision), jax.random.fold_in(slice_key, decision))
    return np.asarray((aux["z"] - mu) / (strategy.alpha * jnp.exp(log_std)))

  held = registry.make_strategy("soe", hold=3)
  eps = [noise(held, j) for j in range(6)]
  for j in (1, 2, 4, 5):  # decisions 0-2 share one draw, 3-5 the next
    np.testing.assert_allclose(eps[j], eps[3 * (j // 3)], atol=1e-4)
  assert np.abs(eps[3] - eps[0]).min() > 1e-3  # a fresh draw for every environment
  assert np.abs(eps[0][1:] - eps[0][:1]).min() > 1e-3  # each environment its own noise
  fresh = registry.make_strategy("soe")  # hold 1: a new draw every decision, as before holding existed
  assert np.abs(noise(fresh, 1) - noise(fresh, 0)).min() > 1e-3
  with pytest.raises(ValueError, match="at least 1"):
    registry.make_strategy("soe", hold=0)


def test_dp_and_sime_use_the_base_path():
  policy = _policy()
  agent = _agent(policy)
  obs = jax.random.uniform(jax.random.PRNGKey(3), (4, 2, OBS_DIM), minval=0, maxval=2)
  key = jax.random.PRNGKey(5)
  base, _ = registry.make_strategy("dp")(agent, obs, None, key)
  assert base.shape == (4, policy.n_action_steps, ACTION_DIM)
  full = agent.normalizer.unnormalize_actions(policy.sample(agent.params, agent.normalizer.normalize_obs(obs), key))
  np.testing.assert_allclose(base, full[:, 1:9], atol=1e-6)  # Diffusion Policy executes chunk[To-1 : To-1+Ta]
  tiny = sime.Sime(scale=1e-9)(agent, obs, None, key)[0]
  np.testing.assert_allclose(tiny, base, atol=1e-4)
  big = sime.Sime(scale=1.0)(agent, obs, None, key)[0]
  assert float(jnp.max(jnp.abs(big - base))) > 1e-3


POSITIONS = lambda a: a[..., None, :3]  # one arm, its position first


@pytest.mark.slow
def test_steering_candidates_vary_one_dimension_and_are_distinct():
  policy = _policy()
  agent = _agent(policy)
  obs = jax.random.uniform(jax.random.PRNGKey(3), (3, 2, OBS_DIM), minval=0, maxval=2)
  cands, dim_of = steering.candidates(
    agent, obs, jax.random.PRNGKey(0), (2, 0), alpha=2.0, num_proposals=12, num_choices=4, positions=POSITIONS
  )
  assert cands.shape == (3, 8, policy.n_action_steps, ACTION_DIM)
  np.testing.assert_array_equal(dim_of, [2, 2, 2, 2, 0, 0, 0, 0])
  # Farthest point sampling never picks the same proposal twice: the 4 per dimension differ.
  for b in range(3):
    for j in range(2):
      paths = np.asarray(cands[b, 4 * j : 4 * j + 4, :, :3]).reshape(4, -1)
      assert len({tuple(np.round(p, 6)) for p in paths}) == 4


def test_steer_picks_the_chosen_candidate_at_every_kth_decision():
  """Steer picks the candidate the chooser names, and only at every k-th decision (the base path between)."""
  policy = _policy()
  agent = _agent(policy)
  obs = jax.random.uniform(jax.random.PRNGKey(3), (2, 2, OBS_DIM), minval=0, maxval=2)

  @dataclasses.dataclass(frozen=True)
  class Last:  # always the last candidate
    def __call__(self, candidates, env_state, key):
      b, c = candidates.shape[:2]
      return jnp.full(b, c - 1), jnp.zeros(b)

  steering_strategy = steer.SoeSteer(
    chooser=Last(), positions=POSITIONS, dims=(1,), num_proposals=8, num_choices=3, every=2
  )
  key = jax.random.PRNGKey(9)
  state = lambda step: type("S", (), {"info": {"steps": jnp.full(2, step)}})()
  chunk, aux = steering_strategy(agent, obs, state(0), key)
  _, key_steer, _ = jax.random.split(key, 3)
  cands, _ = steering.candidates(agent, obs, key_steer, (1,), 2.0, 8, 3, POSITIONS)
  np.testing.assert_allclose(chunk, cands[:, -1], atol=1e-4)
  assert aux["steered"].all() and (aux["dim"] == 1).all()
  chunk, aux = steering_strategy(agent, obs, state(8), key)  # decision 1 of every 2: the base path
  assert not aux["steered"].any() and (aux["dim"] == -1).all()


def test_effective_dims_are_ordered_by_snr():
  snr = jnp.array([1.0, -3.0, 5.0, 0.5])
  assert steering.effective_dims(snr) == (2, 0, 3)
  assert steering.effective_dims(snr, max_dims=2) == (2, 0)
  assert steering.effective_dims(snr, threshold_db=2.0) == (2,)


def test_steering_prepare_picks_the_effective_dims_of_the_data():
  from soe_jax.data import buffer

  policy = _policy()
  agent = _agent(policy)
  rng = np.random.default_rng(1)
  buf = buffer.create(4, 30, OBS_DIM, ACTION_DIM)
  buf = buffer.add(
    buf, rng.uniform(0, 2, (4, 30, OBS_DIM)), np.zeros((4, 30, ACTION_DIM)), np.full(4, 30), np.ones(4, bool), 0
  )
  strategy = steer.SoeSteer(chooser=None, max_dims=2, snr_windows=64)
  prepared, record = strategy.prepare(agent, buf, jax.random.PRNGKey(0))
  snr = strategy.snr(agent, buf, jax.random.PRNGKey(0))
  assert prepared.dims == steering.effective_dims(snr, 0.0, 2) and record["steer_dims"] == list(prepared.dims)
  assert len(record["snr_db"]) == policy.p_net.latent_dim
  assert registry.make_strategy("soe").prepare(agent, buf, jax.random.PRNGKey(0)) == (registry.make_strategy("soe"), {})


@pytest.mark.parametrize("name", registry.strategy_names())
def test_every_strategy_builds_from_its_defaults_refusing_others(name):
  """Every strategy is built from its default settings, and refuses other settings."""
  settings = registry.default_settings(name)
  strategy = registry.make_strategy(name, _env(), **settings)
  assert strategy.name == name
  assert all(getattr(strategy, k) == v for k, v in settings.items())
  with pytest.raises(ValueError, match=f"strategy '{name}' has no setting 'speed'; its settings: "):
    registry.make_strategy(name, _env(), speed=1.0)


def _env():
  from soe_jax.envs.registry import make_env

  return make_env("lift")


def test_unknown_strategy_lists_the_known_ones():
  with pytest.raises(ValueError, match="known strategies: dp, expert, sime, soe, soe_steer"):
    registry.make_strategy("noise")
  with pytest.raises(ValueError, match="needs its environment"):
    registry.make_strategy("soe_steer")
