"""Exploration keys never repeat: two connections' SOE episodes from the same start differ, so do those of
a server restarted with the same seed, and the key each recorded frame names samples its chunk again;
the recording marks the frames the policy decided at."""

import numpy as np
import pytest
import websockets.sync.client as ws_client

from soe_jax.data import lerobot
from soe_jax.data.spec import PolicySpec
from soe_jax.policies import agent as agent_lib
from soe_jax.serve import modes as modes_lib
from soe_jax.serve import recorder as recorder_lib
from soe_jax.serve import session, wire
from soe_jax.serve.server import PolicyServer
from tests.serve.test_policy_server import SPEC, TOKEN, _agent


@pytest.fixture(scope="module")
def served(tmp_path_factory):
  spec = PolicySpec.from_dict(dict(SPEC, observations={"observation.state": SPEC["observations"]["state"]}))
  agent = _agent(spec)
  modes = modes_lib.Modes(agent, spec)
  rec = recorder_lib.Recorder(str(tmp_path_factory.mktemp("keys") / "rec"), spec)
  server = PolicyServer(agent, spec, TOKEN, port=0, modes=modes, default_mode="soe", recorder=rec).start()
  yield server, agent, spec, modes, rec
  server.shutdown()


def _connect(server):
  return ws_client.connect(f"ws://127.0.0.1:{server.port}", additional_headers={"Authorization": f"Api-Key {TOKEN}"})


def _ask(ws, request: dict) -> dict:
  ws.send(wire.packb(request))
  return wire.unpackb(ws.recv())


def test_two_connections_soe_episodes_from_the_same_start_differ(served):
  server, agent, spec, modes, _ = served
  start = {"observation.state": np.linspace(-0.2, 0.2, 7).astype(np.float32), "episode_start": True}
  with _connect(server) as a, _connect(server) as b:  # a robot script that reconnects per episode, or two robots
    a.recv(), b.recv()  # the metadata
    first, second = _ask(a, start)["actions"], _ask(b, start)["actions"]
    again = _ask(a, start)["actions"]  # the first connection's next episode
  assert np.abs(first - second).max() > 1e-4 and np.abs(first - again).max() > 1e-4
  # A server restarted with the same seed (a session with the same seed, a later instance) repeats none.
  restarted = session.Session(agent, spec, session.Keys(server.keys.seed), modes, "soe").infer(start)["actions"]
  assert min(np.abs(restarted - x).max() for x in (first, second, again)) > 1e-4


def test_a_recorded_key_samples_the_recorded_chunk_again(served):
  server, agent, spec, modes, rec = served
  rng = np.random.default_rng(3)
  ta = agent.policy.n_action_steps
  with _connect(server) as ws:
    ws.recv()
    obs0 = rng.uniform(-0.2, 0.2, 7).astype(np.float32)
    reply = _ask(ws, {"observation.state": obs0, "episode_start": True})
    since = rng.uniform(-0.2, 0.2, (ta, 7)).astype(np.float32)
    reply2 = _ask(ws, {"observation.state": since})
    end = {"observation.state": rng.uniform(-0.2, 0.2, (ta, 7)).astype(np.float32), "episode_end": True}
    assert _ask(ws, dict(end, label="success"))["recorded"]["written"]
  ep = lerobot.read_dataset(rec.dataset)[1][-1]
  keys = ep["columns"]["request_key"]
  assert keys.shape == (2 * ta, 4)
  assert (keys[:, :2] == [server.keys.seed, server.keys.instance]).all()
  assert (keys[:ta, 3] == 0).all() and (keys[ta:, 3] == 1).all() and len(set(keys[:, 2])) == 1
  # Each reply's first frame is a decision (what a re-fit's windows aligned to decisions start at).
  np.testing.assert_array_equal(ep["columns"]["decision"], np.arange(2 * ta) % ta == 0)
  np.testing.assert_array_equal(ep["actions"], np.concatenate([reply["actions"], reply2["actions"]]))
  # From the recording alone: the first frame's observation and its key give the first chunk again.
  x = session.policy_input(spec, {k: v[0] for k, v in ep["obs"].items()})
  history = agent_lib.initial_history(x, agent.policy.n_obs_steps)
  again = np.asarray(modes("soe", agent, history, session.request_key(*map(int, keys[0]))))[0]
  np.testing.assert_allclose(again, ep["actions"][:ta], atol=1e-6)
