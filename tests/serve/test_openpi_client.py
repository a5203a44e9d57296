"""openpi's own client against our policy server: openpi-client 0.1.2 from PyPI (`WebsocketClientPolicy` with its
`api_key`, wrapped in `ActionChunkBroker(policy, action_horizon=metadata["action_horizon"])`) gets, step by step, the
rows of the chunks the policy gives in-process, and a client with a wrong or no key is refused with HTTP 401.

openpi-client pins numpy<2, so it runs in its own virtual environment under $SOE_JAX_VENVS (default /work/venvs),
made once; the test skips, saying why, where pip cannot install it. openpi-client 0.1.2 imports typing_extensions
without declaring it, so that is installed alongside. Its `_wait_for_server` connects once (no retry): a refused
handshake raises websockets' `InvalidStatus`, a closed port `ConnectionRefusedError`.

What the client sends, as its msgpack_numpy packs it: each array as {__ndarray__, data: tobytes(), dtype, shape} (a
strided view is sent in C order), numpy scalars as {__npgeneric__, data: item(), dtype} (here `episode_start` as
np.bool_, `timestamp` as np.float64), other keys as they are (a `prompt` string, which the server ignores).
"""

import json
import os
import subprocess

import numpy as np
import pytest

from soe_jax.data.spec import PolicySpec
from soe_jax.policies import agent as agent_lib
from soe_jax.serve import session
from soe_jax.serve.server import PolicyServer
from tests import venvs
from tests.serve.test_policy_server import SPEC, _agent

VERSION = "0.1.2"
PACKAGES = [f"openpi-client=={VERSION}", "typing_extensions"]
PROBE = (
  "import importlib.metadata as m, openpi_client.websocket_client_policy, openpi_client.action_chunk_broker; "
  f"assert m.version('openpi-client') == {VERSION!r}"
)
TOKEN = "openpi-client-token"

# Run with the venv's python; reads {"port", "token", "states": (N, D)} on stdin and prints one JSON line.
CLIENT = """
import json, sys
import numpy as np
from openpi_client import action_chunk_broker, websocket_client_policy

args = json.load(sys.stdin)
columns = np.ascontiguousarray(np.asarray(args["states"], np.float32).T)  # (D, N): each state a strided view
policy = websocket_client_policy.WebsocketClientPolicy(host="127.0.0.1", port=args["port"], api_key=args["token"])
metadata = policy.get_server_metadata()
broker = action_chunk_broker.ActionChunkBroker(policy, action_horizon=metadata["action_horizon"])
steps = []
for i in range(columns.shape[1]):
  obs = {"state": columns[:, i], "episode_start": np.bool_(i == 0), "timestamp": np.float64(100.0 + 0.1 * i),
         "prompt": "pick up the cube"}
  out = broker.infer(obs)
  a = out["actions"]
  steps.append(dict(actions=a.tolist(), dtype=str(a.dtype), shape=list(a.shape), timestamp=float(out["timestamps"]),
                    timing=sorted(out["server_timing"])))
refused = []
for key in ["wrong-" + args["token"], None]:
  try:
    websocket_client_policy.WebsocketClientPolicy(host="127.0.0.1", port=args["port"], api_key=key)
    refused.append(None)
  except Exception as e:
    status = getattr(getattr(e, "response", None), "status_code", None)
    refused.append(dict(type=type(e).__module__ + "." + type(e).__qualname__, status=status, message=str(e)))
print(json.dumps(dict(metadata=metadata, steps=steps, refused=refused)))
"""


@pytest.mark.slow
def test_openpi_client_gets_the_in_process_chunks_step_by_step():
  python = venvs.python("openpi-client", PACKAGES, PROBE)
  spec = PolicySpec.from_dict(SPEC)
  agent = _agent(spec)
  to, ta = agent.policy.n_obs_steps, agent.policy.n_action_steps
  states = np.random.default_rng(2).normal(size=(2 * ta, 7)).astype(np.float32)  # two chunks' worth of steps
  server = PolicyServer(agent, spec, TOKEN, port=0, instance=0).start()
  try:
    args = json.dumps(dict(port=server.port, token=TOKEN, states=states.tolist()))
    r = subprocess.run([python, "-c", CLIENT], input=args, capture_output=True, text=True, timeout=180)
  finally:
    server.shutdown()
  assert r.returncode == 0, r.stderr[-3000:]
  out = json.loads(r.stdout.strip().splitlines()[-1])

  assert out["metadata"]["spec"] == spec.to_dict() and out["metadata"]["action_horizon"] == ta
  assert out["metadata"] == json.loads(json.dumps(server.metadata))

  # The broker queries the server at steps 0 and Ta only: the server's history is obs 0 repeated To times, then
  # (obs 0 x To-1, obs Ta); the observations in between never leave the client.
  first = agent_lib.initial_history(states[0][None], to)
  second = agent_lib.push_history(first, states[ta][None])
  np.testing.assert_array_equal(np.asarray(second)[0], np.stack([states[0]] * (to - 1) + [states[ta]]))
  steps = out["steps"]
  assert len(steps) == 2 * ta
  for query, history in enumerate([first, second]):
    expected = np.asarray(agent.executed(agent.chunk(history, session.request_key(0, 0, 0, query))))[0]
    got = np.array([s["actions"] for s in steps[query * ta : (query + 1) * ta]], np.float32)
    np.testing.assert_allclose(got, expected, atol=1e-6)
  # had the server seen every observation, its second history would end with obs Ta-1, Ta: not what it replied
  if to > 1:
    every = agent_lib.push_history(agent_lib.initial_history(states[ta - 1][None], to), states[ta][None])
    wrong = np.asarray(agent.executed(agent.chunk(every, session.request_key(0, 0, 0, 1))))[0]
    assert not np.allclose(np.array([s["actions"] for s in steps[ta:]]), wrong, atol=1e-6)
  for i, s in enumerate(steps):
    assert s["dtype"] == "float32" and s["shape"] == [10] and "infer_ms" in s["timing"]
    assert s["timestamp"] == pytest.approx(100.0 + 0.1 * i)  # reply i // Ta's stamp + (i % Ta) / control_hz

  # openpi-client 0.1.2 does not retry a refused handshake: websockets raises InvalidStatus with the 401
  for refused in out["refused"]:
    assert refused is not None and refused["type"] == "websockets.exceptions.InvalidStatus", refused
    assert refused["status"] == 401 and "HTTP 401" in refused["message"]


# The robot's helper (soe_jax/serve/client.py, loaded from its file) over openpi-client: a toy robot whose state
# moves towards each commanded position; three episodes in SOE mode labelled success, discard and failure.
HELPER = """
import importlib.util, json, sys
import numpy as np

args = json.load(sys.stdin)
spec = importlib.util.spec_from_file_location("helper", args["helper"])
helper = importlib.util.module_from_spec(spec)
spec.loader.exec_module(helper)
runner = helper.EpisodeRunner("127.0.0.1", args["port"], api_key=args["token"])
rng = np.random.default_rng(0)
episodes = []
for i, label in enumerate(["success", "discard", "failure"]):
  robot = {"x": rng.uniform(-0.1, 0.1, 7).astype(np.float32)}
  seen, sent = [], []
  def observe():
    seen.append(robot["x"].tolist())
    return {"observation.state": robot["x"].copy()}
  def act(a):
    sent.append(np.asarray(a).tolist())
    robot["x"] = (robot["x"] + 0.5 * np.pad(np.asarray(a[:3]) - robot["x"][:3], (0, 4))).astype(np.float32)
  out = runner.run_episode(observe, act, mode="soe", max_steps=11, label=lambda: label, start_state=i)
  episodes.append(dict(recorded=out, seen=seen, sent=sent))
print(json.dumps(dict(numpy=np.__version__, episodes=episodes, modules=sorted(m for m in sys.modules if "soe_jax" in m))))
"""


@pytest.mark.slow
def test_the_robot_helper_runs_in_the_openpi_client_environment(tmp_path):
  import soe_jax.serve
  from soe_jax.data import lerobot
  from soe_jax.serve import modes as modes_lib
  from soe_jax.serve import recorder

  python = venvs.python("openpi-client", PACKAGES, PROBE)
  spec = PolicySpec.from_dict(dict(SPEC, observations={"observation.state": SPEC["observations"]["state"]}))
  agent = _agent(spec)
  rec = recorder.Recorder(str(tmp_path / "rec"), spec)
  modes = modes_lib.Modes(agent, spec)
  server = PolicyServer(agent, spec, TOKEN, port=0, modes=modes, recorder=rec).start()
  helper = os.path.join(os.path.dirname(soe_jax.serve.__file__), "client.py")
  try:
    args = json.dumps(dict(port=server.port, token=TOKEN, helper=helper))
    r = subprocess.run([python, "-c", HELPER], input=args, capture_output=True, text=True, timeout=180)
  finally:
    server.shutdown()
  assert r.returncode == 0, r.stderr[-3000:]
  out = json.loads(r.stdout.strip().splitlines()[-1])
  assert out["numpy"].startswith("1.") and out["modules"] == []  # numpy < 2, nothing of soe_jax
  written = [e for e in out["episodes"] if e["recorded"]["written"]]
  assert [e["recorded"]["label"] for e in out["episodes"]] == ["success", "discard", "failure"] and len(written) == 2
  _, eps = lerobot.read_dataset(rec.dataset)
  for ep, sent in zip(eps, written):
    np.testing.assert_allclose(ep["actions"], np.asarray(sent["sent"], np.float32))  # every executed step
    np.testing.assert_allclose(ep["obs"]["observation.state"], np.asarray(sent["seen"][:-1], np.float32))
    assert (ep["columns"]["mode"] == modes_lib.MODES.index("soe")).all()
  assert [ep["success"] for ep in eps] == [True, False] and [int(ep["columns"]["start_state"][0]) for ep in eps] == [
    0,
    2,
  ]
