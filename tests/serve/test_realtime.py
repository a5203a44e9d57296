"""Real-time chunks: the schedule's aggregation of overlapping chunks by their timestamps and its late
actions dropped; the robot-side helper asking for the next chunk while executing this one, against a
server with delay injected each way, recording exactly the actions executed with the observations
they were executed from; such episodes re-fit on every window; the blocking loop unchanged."""

import importlib.util
import sys

import numpy as np
import pytest
import websockets.sync.client as ws_client

from soe_jax.data import lerobot
from soe_jax.data.episodes import EpisodeSet
from soe_jax.data.spec import PolicySpec
from soe_jax.robot import run
from soe_jax.serve import client, recorder, session
from soe_jax.serve.server import PolicyServer
from tests.serve.test_policy_server import SPEC, TOKEN, _agent

STATE = "observation.state"
DT = 0.1


def _chunk(values, first_tick: int, t0: float = 100.0):
  """Actions (T, 1) of `values`, due one tick apart from tick `first_tick`."""
  return np.asarray(values, np.float32)[:, None], t0 + DT * (first_tick + np.arange(len(values)))


def test_latest_wins_takes_the_newest_chunk_where_chunks_overlap():
  s = client.Schedule(100.0, DT, "latest")
  assert s.add(*_chunk([0, 1, 2, 3], 0), request=0, now=0) == 0
  assert s.add(*_chunk([10, 11, 12, 13], 2), request=1, now=1) == 0
  assert s.remaining(1) == 5  # ticks 1 .. 5
  assert [s.pop(t) for t in range(1, 6)] == [
    (pytest.approx([1.0]), 0), (pytest.approx([10.0]), 1), (pytest.approx([11.0]), 1), (pytest.approx([12.0]), 1),
    (pytest.approx([13.0]), 1)]  # fmt: skip
  assert s.pop(6) is None and s.remaining(6) == 0


def test_a_temporal_ensemble_averages_overlapping_chunks_oldest_weighted_most():
  s = client.Schedule(100.0, DT, "ensemble", ensemble_k=0.5)
  s.add(*_chunk([0, 1, 2, 3], 0), request=0, now=0)
  s.add(*_chunk([10, 11, 12, 13], 2), request=1, now=1)
  s.add(*_chunk([20, 21], 3), request=2, now=2)
  assert s.pop(1) == (pytest.approx([1.0]), 0)
  w = np.exp(-0.5 * np.arange(3))
  action, source = s.pop(3)  # chunks 0, 1 and 2 all have tick 3
  assert source == 2 and action == pytest.approx([(w @ [3.0, 11.0, 20.0]) / w.sum()])
  assert s.pop(4)[0] == pytest.approx([(w[:2] @ [12.0, 21.0]) / w[:2].sum()])
  even = client.Schedule(100.0, DT, "ensemble", ensemble_k=0.0)
  even.add(*_chunk([0, 2], 0), request=0, now=0)
  even.add(*_chunk([4], 1), request=1, now=0)
  assert even.pop(1)[0] == pytest.approx([3.0])  # k = 0: the plain mean


def test_actions_whose_tick_has_passed_are_dropped():
  s = client.Schedule(100.0, DT)
  assert s.add(*_chunk([0, 1, 2, 3], 0), request=0, now=2) == 2  # ticks 0 and 1 passed on arrival
  assert s.pop(2)[0] == pytest.approx([2.0]) and s.dropped == 2
  late = client.Schedule(100.0, DT)
  assert late.add(*_chunk([0, 1, 2], 0), request=0, now=7) == 2  # all late: the last is due now
  assert late.pop(7)[0] == pytest.approx([2.0])
  with pytest.raises(ValueError, match="3 actions with 2 timestamps"):
    s.add(np.zeros((3, 1)), [1.0, 2.0], request=1, now=0)


@pytest.mark.parametrize(
  "settings, message",
  [
    (dict(aggregate="mean"), "unknown aggregate 'mean'; known: latest, ensemble"),
    (dict(threshold=-1), "threshold must be a whole number of actions >= 0 (or None), got -1"),
    (dict(ensemble_k=-0.1), "ensemble_k must be a number >= 0, got -0.1"),
  ],
)
def test_bad_settings_are_one_line_errors(settings, message):
  with pytest.raises(ValueError, match=message.replace("(", r"\(").replace(")", r"\)")):
    client.RealTime(**settings)


class _DelayedPolicy:
  """A websocket client with `delay` seconds each way, keeping every request it sent."""

  def __init__(self, ws, delay: float):
    from soe_jax.bench.realtime import DelayedPolicy

    self.inner, self.sent = DelayedPolicy(ws, delay), []

  def get_server_metadata(self):
    return self.inner.get_server_metadata()

  def infer(self, obs):
    self.sent.append(obs)
    return self.inner.infer(obs)


class _Robot:
  """A robot whose observation is a count of the commands it took (and the last one's first number):
  what each recorded frame holds can be checked against what was executed."""

  def __init__(self):
    self.acted, self.observed = [], []

  def observe(self):
    obs = {STATE: np.r_[len(self.acted), self.acted[-1][0] if self.acted else 0.0, np.zeros(5)].astype(np.float32)}
    self.observed.append(obs[STATE])
    return obs

  def act(self, action):
    self.acted.append(np.asarray(action, np.float32))


@pytest.fixture(scope="module")
def served(tmp_path_factory):
  spec = PolicySpec.from_dict(dict(SPEC, observations={STATE: SPEC["observations"]["state"]}, control_hz=25.0))
  rec = recorder.Recorder(str(tmp_path_factory.mktemp("realtime") / "rec"), spec)
  server = PolicyServer(_agent(spec), spec, TOKEN, port=0, recorder=rec).start()
  yield server, spec, rec
  server.shutdown()


def _episode(server, realtime, steps: int, delay: float = 0.02):
  robot = _Robot()
  with ws_client.connect(f"ws://127.0.0.1:{server.port}", additional_headers={"Authorization": f"Api-Key {TOKEN}"},
                         max_size=None) as ws:  # fmt: skip
    policy = _DelayedPolicy(ws, delay)
    runner = client.EpisodeRunner(policy=policy, realtime=realtime)
    out = runner.run_episode(robot.observe, robot.act, max_steps=steps, label=lambda: "success")
  return robot, policy, runner, out


@pytest.mark.parametrize("aggregate", ["latest", "ensemble"])
def test_real_time_chunks_record_what_was_executed_from_what_was_observed(served, aggregate):
  server, spec, rec = served
  robot, policy, runner, out = _episode(server, client.RealTime(threshold=4, aggregate=aggregate), steps=30)
  assert out["written"]
  ep = lerobot.read_dataset(rec.dataset)[1][out["dataset_episode"]]
  # Every tick is a frame: the action sent then (new or held) and the observation it was sent from.
  assert len(robot.acted) == 30 and runner.stats["ticks"] == 30
  np.testing.assert_allclose(ep["actions"], np.stack(robot.acted), atol=1e-6)
  np.testing.assert_array_equal(ep["obs"][STATE][:, 0], np.arange(30))  # one command more per frame
  np.testing.assert_array_equal(ep["obs"][STATE], np.stack(robot.observed[:30]))
  # The next chunk was asked for while this one executed, and those due before its reply came were dropped.
  sent = policy.sent[1:-1]
  assert runner.stats["requests"] == len(policy.sent) - 1 > 2 and runner.stats["dropped"] > 0
  assert all("executed" in r and len(r["executed"]) == len(r[STATE]) for r in policy.sent[1:])
  # Each frame names the request its action came from; a decision is a frame a request was sampled from.
  keys = ep["columns"]["request_key"]
  sources = np.concatenate([r["executed_from"] for r in policy.sent[1:]])
  np.testing.assert_array_equal(keys[:, 3], sources)
  ticks = np.cumsum([len(r[STATE]) for r in sent])  # each request's tick
  np.testing.assert_array_equal(np.flatnonzero(ep["columns"]["decision"]), np.r_[0, ticks[ticks < 30]])
  assert not (keys[:, 3][ticks[ticks < 30]] == np.arange(1, 1 + (ticks < 30).sum())).any()  # an earlier chunk's
  # A re-fit takes every window of it, not only those at decisions.
  assert run._without_decisions([EpisodeSet([dict(ep, episode_index=0)], 1)], 8) == ["round 1 episode 0"]


def test_a_decision_every_chunk_from_a_real_time_client_still_refits_every_window():
  """threshold 0 asks when the chunk is used up: decisions every Ta frames, but the frames after each
  are the earlier chunk's held command, then the new one's: not one chunk as sampled."""
  decision = (np.arange(12) % 4 == 0).astype(np.int64)
  held = np.stack([np.zeros(12), np.zeros(12), np.zeros(12), [0, 0, 0, 0, 0, 1, 1, 1, 1, 2, 2, 2]], 1)
  blocking = np.stack([np.zeros(12)] * 3 + [np.arange(12) // 4], 1)

  def episode(key):
    return {"actions": np.zeros((12, 2)), "columns": {"decision": decision, "request_key": key}, "episode_index": 0}

  assert run._without_decisions([EpisodeSet([episode(blocking)], 1)], 4) == []
  assert run._without_decisions([EpisodeSet([episode(held)], 1)], 4) == ["round 1 episode 0"]


def test_the_blocking_loop_sends_and_records_as_before(served):
  server, spec, rec = served
  robot, policy, runner, out = _episode(server, None, steps=20, delay=0.0)
  ep = lerobot.read_dataset(rec.dataset)[1][out["dataset_episode"]]
  assert [sorted(r) for r in policy.sent[:2]] == [sorted([STATE, "episode_start", "mode", "timestamp"]),
                                                  sorted([STATE, "mode", "timestamp"])]  # fmt: skip
  np.testing.assert_allclose(ep["actions"], np.stack(robot.acted), atol=1e-6)
  np.testing.assert_array_equal(ep["columns"]["decision"], np.arange(20) % 8 == 0)
  np.testing.assert_array_equal(ep["columns"]["request_key"][:, 3], np.arange(20) // 8)
  assert runner.stats == dict(ticks=20, idle=0, dropped=0, requests=3)


def test_bad_executed_actions_are_one_line_errors(served):
  _, spec, _ = served
  s = session.Session(_agent(spec), spec)
  with pytest.raises(session.RequestError, match="executed actions with episode_start"):
    s.infer({STATE: np.zeros(7, np.float32), "episode_start": True, "executed": np.zeros((1, 10)),
             "executed_from": np.zeros(1, np.int64)})  # fmt: skip
  s.infer({STATE: np.zeros(7, np.float32), "episode_start": True})
  since = {STATE: np.zeros((2, 7), np.float32)}
  for extra, message in [
    (dict(executed=np.zeros((2, 10))), "executed and executed_from go together"),
    (dict(executed=np.zeros((3, 10)), executed_from=np.zeros(2, np.int64)), r"executed must be 2 x 10 finite .* \[3, 10\]"),
    (dict(executed=np.zeros((2, 10)), executed_from=np.zeros(2)), r"executed_from must be 2 whole numbers .* float64"),
    (dict(executed=np.zeros((2, 10)), executed_from=np.array([0, 1])), "executed_from names request 1, but this "
                                                                        "episode's requests are 0 to 0"),
  ]:  # fmt: skip
    with pytest.raises(session.RequestError, match=message):
      s.infer(dict(since, **extra))


def test_the_realtime_bench_runs_both_loops_and_its_record_is_json(toy_run):
  """`bench realtime` end to end on a fitted checkpoint (the toy task's round 0), one fast rate and one
  start state: both loops run, and the record, the real-time settings included, is JSON."""
  import json

  from soe_jax.bench import realtime as realtime_bench
  from soe_jax.experiment.rundir import RunDir
  from tests.experiment import toy

  _, config, workdir = toy_run
  ckpt = RunDir(workdir, config).ckpt_dir(0)
  with toy.registered():
    out = realtime_bench.run(ckpt, rates=(50.0,), delay_ms=1.0, states=1, realtime=client.RealTime(threshold=2))
  assert json.loads(json.dumps(out))["realtime"] == dict(threshold=2, aggregate="latest", ensemble_k=0.01)
  assert [(r["hz"], r["loop"]) for r in out["results"]] == [(50.0, "blocking"), (50.0, "realtime")]
  assert all(r["requests"] >= 1 and len(r["success"]) == 1 for r in out["results"])


def test_a_realtime_record_gets_a_table():
  from soe_jax.analysis import records

  part = dict(delay_ms_each_way=50.0, load_before=[1.5, 1.0, 1.0], load_after=[1.75, 1.0, 1.0], results=[
    dict(hz=10.0, loop="blocking", idle_s_per_s=0.14, dropped_per_episode=0.0, replaced=0, requests=6,
         success_rate=0.5, success=[1, 0]),
    dict(hz=10.0, loop="realtime", idle_s_per_s=0.04, dropped_per_episode=10.0, replaced=1, requests=12,
         success_rate=1.0, success=[1, 1])])  # fmt: skip
  out = records.table([("lift", dict(kind="realtime", realtime=part, machine="2 cores"))])
  assert "| lift | 10 Hz | realtime | 50 ms | 0.040 s | 10.0 | 1 | 12 | 100.0% of 2 | 1.50 / 1.75 | 2 cores |" in out


def test_the_helper_loads_from_its_file_alone():
  """The robot's side copies `client.py` and loads it by path, outside `sys.modules` (the LeRobot
  example, openpi's environment): nothing in it may need its module registered."""
  spec = importlib.util.spec_from_file_location("copied_helper", client.__file__)
  module = importlib.util.module_from_spec(spec)
  spec.loader.exec_module(module)
  assert module.RealTime(threshold=2).threshold == 2 and "copied_helper" not in sys.modules
