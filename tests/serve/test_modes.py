"""The server's modes and its recorder, in-process: each mode's strategy at the registry's defaults,
each mode's chunk, steering's choice and timeout, episodes recorded from the observations since each
request and written only when labelled, and Table I's numbers from what was written."""

import subprocess
import sys
import types

import numpy as np
import pytest

from soe_jax.analysis import labelled
from soe_jax.commands import serve as serve_command
from soe_jax.data import lerobot
from soe_jax.data.spec import PolicySpec
from soe_jax.explore import registry, sime
from soe_jax.policies import agent as agent_lib
from soe_jax.serve import modes as modes_lib
from soe_jax.serve import recorder as recorder_lib
from soe_jax.serve import session
from tests.serve.test_policy_server import SPEC, _agent

SNR = [6.0, -3.0, 2.0] + [-10.0] * 13  # dims 0 and 2 carry signal


@pytest.fixture(scope="module")
def served():
  spec = PolicySpec.from_dict(dict(SPEC, observations={"observation.state": SPEC["observations"]["state"]}))
  agent = _agent(spec)
  modes = modes_lib.Modes(agent, spec, dict(steer=dict(num_proposals=6, num_choices=2)), SNR)
  return agent, spec, modes


def _obs(rng, k=None):
  shape = (7,) if k is None else (k, 7)
  return {"observation.state": rng.uniform(-0.2, 0.2, size=shape).astype(np.float32)}


def test_every_mode_runs_its_strategy_at_the_registry_defaults(served):
  """A setting's default is written once, in its strategy: every exploring mode built with nothing given
  has its registry entry's defaults (SIME's image scale for an image policy), and the serve command
  states none of its own."""
  agent, spec, _ = served
  modes = modes_lib.Modes(agent, spec, snr_db=SNR)
  assert set(modes_lib.STRATEGIES) == set(modes_lib.MODES) - {"base"}
  for mode, name in modes_lib.STRATEGIES.items():
    defaults = registry.default_settings(name)
    assert modes.settings[mode] == defaults, mode
    assert modes.strategies[mode].name == name
    assert {k: getattr(modes.strategies[mode], k) for k in defaults} == defaults, mode
  soe, sime_, steer = (registry.default_settings(n) for n in ("soe", "sime", "soe_steer"))
  meta = modes.describe()
  assert meta["settings"] == modes.settings
  assert (meta["soe_alpha"], meta["sime_scale"]) == (soe["alpha"], sime_["scale"]) and steer["alpha"] == soe["alpha"]
  assert meta["steer"]["proposals_per_dim"] == steer["num_choices"] and meta["steer"]["threshold_db"] == 0.0
  assert modes.dims == (0, 2)  # steering's max_dims (0: every dimension above its threshold)

  image = types.SimpleNamespace(image_keys=("agentview_image",))
  assert modes_lib.mode_settings(image)["sime"] == dict(sime_, scale=sime.IMAGE_SCALE)
  given = modes_lib.mode_settings(image, dict(soe=dict(alpha=1.0), sime=dict(scale=0.2), steer=dict(max_dims=1)))
  assert (given["soe"]["alpha"], given["sime"]["scale"], given["steer"]["max_dims"]) == (1.0, 0.2, 1)
  assert modes_lib.Modes(agent, spec, dict(steer=dict(max_dims=1)), SNR).dims == (0,)
  with pytest.raises(ValueError, match="strategy 'soe_steer' has no setting 'speed'"):
    modes_lib.mode_settings(agent.policy, dict(steer=dict(speed=1)))
  with pytest.raises(ValueError, match="hold 1"):
    modes_lib.mode_settings(agent.policy, dict(soe=dict(hold=2)))
  for flag in ("alpha", "sime_scale", "steer_dims", "steer_choices"):
    assert serve_command.FLAGS[flag].default is None, flag


def test_the_modes_import_no_simulator():
  """A robot's server reads the strategies' settings without importing `soe_jax.envs`."""
  code = "import sys, soe_jax.serve.modes; print(sorted(m for m in sys.modules if m.startswith('soe_jax.envs')))"
  out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
  assert out.strip() == "[]"


def test_each_mode_gives_its_own_path(served):
  agent, spec, modes = served
  assert modes.available == modes_lib.MODES and modes.dims == (0, 2)
  rng = np.random.default_rng(0)
  o = _obs(rng)
  history = agent_lib.initial_history(session.policy_input(spec, o), agent.policy.n_obs_steps)
  key = session.request_key(0, 0, 0, 0)
  got = {}
  for mode in ("base", "soe", "sime"):
    s = session.Session(agent, spec, session.Keys(0, 0), modes=modes)
    got[mode] = s.infer(dict(o, mode=mode, episode_start=True))["actions"]
  np.testing.assert_allclose(got["base"], np.asarray(agent.act(history, key))[0], atol=1e-6)
  soe = agent.executed(agent.explore_chunk(history, key, 2.0)[0])
  np.testing.assert_allclose(got["soe"], np.asarray(soe)[0], atol=1e-6)
  fn = sime.cond_fn(agent.policy, agent.normalizer, 0.01)
  np.testing.assert_allclose(got["sime"], np.asarray(agent.act(history, key, fn))[0], atol=1e-6)
  assert np.abs(got["soe"] - got["base"]).max() > 1e-4
  with pytest.raises(session.RequestError, match="unknown mode 'explore'; known: base, soe, sime, steer"):
    session.Session(agent, spec, modes=modes).infer(dict(o, mode="explore"))
  plain = modes_lib.Modes(agent, spec)  # no stored SNR: no steering
  assert "steer" not in plain.available and "no stored SNR" in plain.unavailable["steer"]


def test_steering_a_joint_space_arm_spreads_its_proposals_over_the_whole_action():
  """An action with no 3-D position part (an SO-101's joints): steering compiles, and its proposals are
  the farthest apart over the whole action."""
  joints = dict(SPEC, actions=[[["joints", 9], ["gripper", 1]]], observations={"observation.state": {"shape": [7],
                "dtype": "float32"}})  # fmt: skip
  joints.pop("action_box")
  spec = PolicySpec.from_dict(joints)
  agent = _agent(spec)
  modes = modes_lib.Modes(agent, spec, dict(steer=dict(num_proposals=6, num_choices=2)), SNR)
  assert "steer" in modes.available
  x = session.policy_input(spec, _obs(np.random.default_rng(0)))
  history = agent_lib.initial_history(x, agent.policy.n_obs_steps)
  proposals, dims = modes("steer", agent, history, session.request_key(0, 0, 0, 0))
  assert np.asarray(proposals).shape == (1, 2 * len(modes.dims), agent.policy.n_action_steps, 10)
  assert np.abs(np.asarray(proposals)[0, 0] - np.asarray(proposals)[0, 1]).max() > 1e-4


def test_steering_sends_the_chosen_proposal_or_the_base_path_on_timeout(served):
  agent, spec, modes = served
  o = _obs(np.random.default_rng(1))
  seen = []
  pick = lambda s, steering: seen.append(steering) or 3
  reply = session.Session(agent, spec, modes=modes, chooser=pick).infer(dict(o, mode="steer"))
  (steering,) = seen
  assert np.asarray(steering["proposals"]).shape == (4, agent.policy.n_action_steps, 10)
  assert steering["dim_of"] == [0, 0, 2, 2] and reply["steering"]["chosen"] == 3
  np.testing.assert_allclose(reply["actions"], np.asarray(steering["proposals"][3], np.float32))
  keys = session.Keys()
  timed_out = session.Session(agent, spec, keys, modes=modes, chooser=lambda s, st: None).infer(dict(o, mode="steer"))
  base = session.Session(agent, spec, session.Keys(keys.seed, keys.instance), modes=modes).infer(o)
  assert timed_out["steering"]["timed_out"] and timed_out["steering"]["chosen"] is None
  np.testing.assert_allclose(timed_out["actions"], base["actions"])


def _episode(s, rng, decisions, label, start_state=None, stop_after=None):
  """Requests as the robot's helper sends them: the first observation, then the observations after each
  executed action; -> (observations (T+1, 7) in order, actions executed (T, 10))."""
  first = _obs(rng)
  obs, acts = [first["observation.state"]], []
  reply = s.infer(dict(first, episode_start=True))
  for d in range(decisions):
    k = len(reply["actions"]) if stop_after is None or d < decisions - 1 else stop_after
    since = _obs(rng, k)
    acts += list(reply["actions"][:k])
    obs += list(since["observation.state"])
    if d == decisions - 1:
      end = dict(since, episode_end=True, label=label)
      if start_state is not None:
        end["start_state"] = start_state
      return np.stack(obs), np.stack(acts), s.infer(end)["recorded"]
    reply = s.infer(since)


def test_labelled_episodes_are_written_frame_by_frame_and_discarded_ones_not(served, tmp_path):
  agent, spec, modes = served
  rec = recorder_lib.Recorder(str(tmp_path / "rec"), spec, task="reach")
  s = session.Session(agent, spec, modes=modes, recorder=rec)
  rng = np.random.default_rng(2)
  obs0, acts0, r0 = _episode(s, rng, 3, "success", start_state=5, stop_after=3)
  _, _, r1 = _episode(s, rng, 2, "discard")
  obs2, acts2, r2 = _episode(s, rng, 2, "failure", start_state=5)
  assert (r0["written"], r0["dataset_episode"]) == (True, 0) and not r1["written"] and r2["dataset_episode"] == 1
  info, eps = lerobot.read_dataset(rec.dataset)
  assert info["total_episodes"] == 2 and info["fps"] == 10
  for ep, obs, acts, success in [(eps[0], obs0, acts0, True), (eps[1], obs2, acts2, False)]:
    # Frame t: the observation the action was executed from; the last observation closes the episode.
    np.testing.assert_array_equal(ep["obs"]["observation.state"], obs[:-1])
    np.testing.assert_array_equal(ep["actions"], acts)
    assert ep["success"] is success and (ep["columns"]["start_state"] == 5).all()
  assert len(eps[0]["actions"]) == 2 * agent.policy.n_action_steps + 3
  # A new episode_start drops the unlabelled one; a label with no episode under way is refused.
  s.infer(dict(_obs(rng), episode_start=True))
  s.infer(dict(_obs(rng), episode_start=True))
  s.infer(dict(_obs(rng, 1), episode_end=True, label="success"))
  with pytest.raises(session.RequestError, match="no episode is under way"):
    s.infer(dict(episode_end=True, label="success"))
  with pytest.raises(session.RequestError, match="unknown label 'great'"):
    s.infer(dict(_obs(rng), episode_start=True)) and s.infer(dict(_obs(rng, 1), episode_end=True, label="great"))
  assert lerobot.read_info(rec.dataset)["total_episodes"] == 3
  with pytest.raises(session.RequestError, match="9 observations since the last reply, which sent 8 actions"):
    s.infer(dict(_obs(rng), episode_start=True)) and s.infer(_obs(rng, 9))

  table = labelled.table(labelled.read(rec.dataset), k=2)
  base = table["explore"]["modes"]["base"]
  assert (base["episodes"], base["successes"], base["start_states"], base["states_with_k_tries"]) == (3, 2, 1, 1)
  assert base["pass_at_k"] == 1.0 and base["rollouts"] == 1
  ba = labelled.before_after(labelled.read(rec.dataset)["episodes"][1:], labelled.read(rec.dataset)["episodes"][:1])
  assert ba["before"]["rate"] == 0.5 and ba["after"]["rate"] == 1.0 and ba["paired"]["up"] == 1


def test_an_episode_with_unobserved_steps_is_not_written(served, tmp_path):
  """A client that sends one observation per chunk (openpi's plain ActionChunkBroker) while the robot runs the
  whole chunk says nothing of the steps between: the episode is not written wrong."""
  agent, spec, modes = served
  rec = recorder_lib.Recorder(str(tmp_path / "rec"), spec)
  s = session.Session(agent, spec, modes=modes, recorder=rec)
  rng = np.random.default_rng(4)
  ta = agent.policy.n_action_steps
  s.infer(dict(_obs(rng), episode_start=True, timestamp=100.0))
  s.infer(dict(_obs(rng), timestamp=100.0 + ta / 10))
  out = s.infer(dict(_obs(rng, 1), episode_end=True, label="success", timestamp=100.0 + 2 * ta / 10))["recorded"]
  assert not out["written"] and "gaps (one observation without the leading axis after a reply of 8" in out["reason"]
  assert rec.saved == 0 and not (tmp_path / "rec" / "lerobot").exists()
