"""The policy server: openpi's frames, the token and Origin checks, chunk-first replies equal to the
in-process chunk, one error frame per bad request while other clients are served, and the box check."""

import http

import jax
import numpy as np
import pytest
import websockets
import websockets.sync.client as ws_client

from soe_jax.data.spec import PolicySpec
from soe_jax.policies import agent as agent_lib
from soe_jax.policies import normalizer
from soe_jax.policies.agent import Agent
from soe_jax.policies.policy import policy_from_spec
from soe_jax.serve import session, wire
from soe_jax.serve.server import PolicyServer
from tests.experiment import toy

TOKEN = "secret-token"
SPEC = dict(
  observations={"state": {"shape": [7], "dtype": "float32"}},
  actions=[[["position", 3], ["rotation_6d", 6], ["gripper", 1]]],
  action_frame="world",
  control_hz=10.0,
  action_box=[{"position": [[-0.5, -0.5, 0.0], [0.5, 0.5, 1.0]]}],
)


def _agent(spec: PolicySpec, box=None) -> Agent:
  policy = policy_from_spec(toy.get_config("smoke").policy, spec)
  rng = np.random.default_rng(0)
  obs, actions = rng.normal(size=(50, 7)), rng.uniform(-0.3, 0.3, size=(50, 10))
  norm = normalizer.fit(obs, actions, action_box=box if box is not None else spec.action_bounds())
  return Agent(policy, policy.init(jax.random.key(0)), norm)


@pytest.fixture(scope="module")
def served():
  spec = PolicySpec.from_dict(SPEC)
  agent = _agent(spec)
  server = PolicyServer(agent, spec, TOKEN, port=0, instance=0).start()
  yield server, agent, spec
  server.shutdown()


def _connect(server, token=TOKEN, origin=None):
  headers = {"Authorization": f"Api-Key {token}"} if token else None
  return ws_client.connect(f"ws://127.0.0.1:{server.port}", additional_headers=headers, origin=origin,
                           compression=None, max_size=None)  # fmt: skip


def test_replies_are_chunk_first_and_equal_the_in_process_chunk(served):
  server, agent, spec = served
  with _connect(server) as ws:
    meta = wire.unpackb(ws.recv())
    assert meta["spec"] == spec.to_dict() and meta["action_horizon"] == agent.policy.n_action_steps
    rng = np.random.default_rng(1)
    observations = [rng.normal(size=7).astype(np.float32) for _ in range(3)]
    replies = []
    for i, o in enumerate(observations):
      start = np.array(i == 0) if i == 1 else i == 0  # (openpi-client packs 0-d arrays as arrays)
      ws.send(wire.packb({"state": o, "episode_start": start, "timestamp": np.array(100.0 + i)}))
      replies.append(wire.unpackb(ws.recv()))
  ta = agent.policy.n_action_steps
  history = agent_lib.initial_history(observations[0][None], agent.policy.n_obs_steps)
  for i, (o, r) in enumerate(zip(observations, replies)):
    if i:
      history = agent_lib.push_history(history, o[None])
    expected = np.asarray(agent.executed(agent.chunk(history, session.request_key(0, 0, 0, i))))[0]
    assert r["actions"].shape == (ta, 10) and r["actions"].dtype == np.float32
    np.testing.assert_allclose(r["actions"], expected, atol=1e-6)
    np.testing.assert_allclose(r["timestamps"], 100.0 + i + np.arange(ta) / 10.0)
    assert r["server_timing"]["infer_ms"] > 0 and ("prev_total_ms" in r["server_timing"]) == (i > 0)


def test_strangers_are_refused_at_the_handshake(served):
  server, _, _ = served
  for token, origin, status in [(None, None, 401), ("wrong", None, 401), (TOKEN, "http://evil.example", 403)]:
    with pytest.raises(websockets.InvalidStatus) as e:
      _connect(server, token, origin)
    assert e.value.response.status_code == status
  import urllib.request

  with urllib.request.urlopen(f"http://127.0.0.1:{server.port}/healthz") as r:
    assert r.status == http.HTTPStatus.OK and r.read() == b"OK\n"


def test_a_bad_request_gets_one_error_frame_and_others_are_served_on(served):
  server, _, _ = served
  with _connect(server) as good:
    good.recv()
    for bad, message in [
      ({"nothing": np.zeros(3)}, r"bad request: missing observation keys \['state'\]"),
      (
        {"state": np.zeros(5, np.float32)},
        r"observation 'state' must be numbers of shape \[7\] \(or k x that\), got float32 \[5\]",
      ),
      ({"state": np.full(7, np.nan, np.float32)}, "is not finite"),
    ]:
      with _connect(server) as ws:
        ws.recv()
        ws.send(wire.packb(bad))
        reply = ws.recv()
        assert isinstance(reply, str)
        assert __import__("re").search(message, reply), reply
        with pytest.raises(websockets.ConnectionClosed):
          ws.recv()
    with _connect(server) as ws:
      ws.recv()
      ws.send(b"\xc1not msgpack")
      assert ws.recv().startswith("bad request: not a msgpack frame")
    good.send(wire.packb({"state": np.zeros(7, np.float32)}))
    assert wire.unpackb(good.recv())["actions"].shape[1] == 10  # still served


def test_a_chunk_outside_the_action_box_is_never_sent():
  """A normaliser wider than the spec's box lets the sampler leave it: an error frame, no actions."""
  spec = PolicySpec.from_dict(SPEC)
  wide = (np.r_[[-50.0] * 3, [-np.inf] * 7], np.r_[[50.0] * 3, [np.inf] * 7])
  server = PolicyServer(_agent(spec, wide), spec, TOKEN, port=0).start()
  try:
    with _connect(server) as ws:
      ws.recv()
      ws.send(wire.packb({"state": np.zeros(7, np.float32)}))
      reply = ws.recv()
      assert isinstance(reply, str) and "leaves the action box" in reply and "nothing was sent" in reply
  finally:
    server.shutdown()


def test_a_frame_over_the_size_limit_closes_that_connection_only():
  spec = PolicySpec.from_dict(SPEC)
  server = PolicyServer(_agent(spec), spec, TOKEN, port=0, max_size=1024).start()
  try:
    with _connect(server) as ws, _connect(server) as other:
      ws.recv(), other.recv()
      ws.send(wire.packb({"state": np.zeros(7, np.float32), "padding": np.zeros(4096, np.uint8)}))
      with pytest.raises(websockets.ConnectionClosed) as closed:
        ws.recv()
      assert closed.value.rcvd.code == 1009  # message too big
      other.send(wire.packb({"state": np.zeros(7, np.float32)}))
      assert wire.unpackb(other.recv())["actions"].shape == (8, 10)
  finally:
    server.shutdown()
