"""The robot's page over HTTP beside the policy server: a steer request waits for the page's choice (or
its timeout, or the robot leaving), an ended episode waits for the page's label, and strangers (no
token, a foreign Host or Origin) are refused before anything is read."""

import contextlib
import http.client
import json
import threading
import time

import numpy as np
import pytest
import websockets.sync.client as ws_client

from soe_jax.data import lerobot
from soe_jax.serve import modes as modes_lib
from soe_jax.serve import page, recorder, wire
from soe_jax.serve.server import PolicyServer
from tests.serve.test_modes import SNR, _obs, served  # noqa: F401 (the module fixture)

TOKEN = "page-token"


@pytest.fixture()
def running(served, tmp_path):  # noqa: F811
  agent, spec, modes = served
  rec = recorder.Recorder(str(tmp_path / "rec"), spec)
  server = PolicyServer(agent, spec, TOKEN, port=0, modes=modes, recorder=rec, steer_timeout=3.0).start()
  httpd = page.serve(server, "127.0.0.1", 0)
  threading.Thread(target=httpd.serve_forever, daemon=True).start()
  yield server, httpd.server_address[1], rec
  httpd.shutdown()
  httpd.server_close()
  server.shutdown()


def _request(port, method, path, body=None, token=TOKEN, host=None, origin=None):
  conn = http.client.HTTPConnection("127.0.0.1", port, timeout=10)
  headers = {"Host": host or f"127.0.0.1:{port}"}
  if token:
    headers["Authorization"] = f"Api-Key {token}"
  if origin:
    headers["Origin"] = origin
  data = None if body is None else json.dumps(body).encode()
  if data is not None:
    headers["Content-Type"] = "application/json"
  conn.request(method, path, data, headers)
  r = conn.getresponse()
  raw = r.read()
  return r.status, (json.loads(raw) if r.getheader("Content-Type", "").startswith("application/json") else raw)


@contextlib.contextmanager
def _robot(server):
  with ws_client.connect(f"ws://127.0.0.1:{server.port}", additional_headers={"Authorization": f"Api-Key {TOKEN}"},
                         compression=None, max_size=None) as ws:  # fmt: skip
    wire.unpackb(ws.recv())  # the metadata
    yield ws


def _wait_for(port, predicate, timeout=10.0):
  deadline = time.monotonic() + timeout
  while time.monotonic() < deadline:
    status, view = _request(port, "GET", "/api/state")
    assert status == 200
    if predicate(view):
      return view
    time.sleep(0.05)
  raise AssertionError(f"the page never showed it: {view}")


def test_strangers_are_refused(running):
  server, port, _ = running
  assert _request(port, "GET", "/api/state", token=None)[0] == 401
  assert _request(port, "GET", "/api/state", token="wrong")[0] == 401
  assert _request(port, "GET", "/api/state", host="evil.example:80")[0] == 403  # DNS rebinding
  assert _request(port, "POST", "/api/label", {"connection": "c1"}, origin="http://evil.example")[0] == 403
  status, html = _request(port, "GET", f"/?token={TOKEN}", token=None)
  assert status == 200 and b"soe_jax robot" in html
  status, err = _request(port, "POST", "/api/choose", {"connection": "c9", "request": "0-0", "index": 0})
  assert status == 400 and "no connection 'c9'" in err["error"]


def test_a_steer_request_waits_for_the_page_and_sends_the_choice(running):
  server, port, _ = running
  with _robot(server) as ws:
    replies = []
    t = threading.Thread(target=lambda: ws.send(wire.packb(dict(_obs(np.random.default_rng(0)), mode="steer")))
                         or replies.append(wire.unpackb(ws.recv())))  # fmt: skip
    t.start()
    view = _wait_for(port, lambda v: v["connections"] and (v["connections"][0]["steering"] or {}).get("waiting"))
    c = view["connections"][0]
    assert len(c["steering"]["paths"]) == 4 and len(c["steering"]["paths"][0][0]) == server.agent.policy.n_action_steps
    assert view["dims"] == [0, 2] and view["snr_db"] == SNR
    status, err = _request(port, "POST", "/api/choose", {"connection": c["name"], "request": c["steering"]["request"],
                                                        "index": 7})  # fmt: skip
    assert status == 400 and "choose one of 0 .. 3" in err["error"]
    status, _ = _request(port, "POST", "/api/choose", {"connection": c["name"], "request": c["steering"]["request"],
                                                      "index": 2})  # fmt: skip
    assert status == 200
    t.join(10)
    (reply,) = replies
    assert reply["steering"]["chosen"] == 2 and not reply["steering"]["timed_out"]
    np.testing.assert_allclose(reply["actions"], np.asarray(reply["steering"]["proposals"][2], np.float32))
    # A second request is not answered in time: the base path, and a late choice is refused with the reason.
    ws.send(wire.packb(dict(_obs(np.random.default_rng(1), 8), mode="steer")))
    late = wire.unpackb(ws.recv())
    assert late["steering"]["timed_out"] and late["steering"]["chosen"] is None
    status, err = _request(port, "POST", "/api/choose", {"connection": c["name"], "request": "0-1", "index": 0})
    assert status == 400 and "timed out after 3 s" in err["error"]
    ws.close()


def test_the_robot_leaving_while_a_steer_request_waits(running):
  server, port, rec = running
  with _robot(server) as ws:
    ws.send(wire.packb(dict(_obs(np.random.default_rng(2)), mode="steer")))
    view = _wait_for(port, lambda v: v["connections"] and (v["connections"][0]["steering"] or {}).get("waiting"))
    c = view["connections"][0]
    ws.close()
    _wait_for(port, lambda v: not v["connections"])  # the half episode is not kept
    status, err = _request(port, "POST", "/api/choose", {"connection": c["name"], "request": "0-0", "index": 0})
    assert status == 400 and "no connection" in err["error"]
    assert rec.saved == 0


def test_the_page_labels_an_ended_episode(running):
  server, port, rec = running
  with _robot(server) as ws:
    rng = np.random.default_rng(3)
    ws.send(wire.packb(dict(_obs(rng), episode_start=True)))
    wire.unpackb(ws.recv())
    ws.send(wire.packb(dict(_obs(rng, 5), episode_end=True)))
    assert wire.unpackb(ws.recv())["recorded"]["awaiting_label"]
    ws.close()  # the robot may leave; the ended episode waits for its label
    view = _wait_for(port, lambda v: v["connections"] and v["connections"][0]["awaiting_label"] == [0])
    name = view["connections"][0]["name"]
    status, err = _request(port, "POST", "/api/label", {"connection": name, "episode": 4, "label": "success"})
    assert status == 400 and "no ended episode 4" in err["error"]
    status, err = _request(port, "POST", "/api/label", {"connection": name, "episode": 0, "label": "maybe"})
    assert status == 400 and "unknown label 'maybe'" in err["error"]
    status, out = _request(port, "POST", "/api/label", {"connection": name, "episode": 0, "label": "success",
                                                        "start_state": 7})  # fmt: skip
    assert status == 200 and out["written"] and out["dataset_episode"] == 0
    (ep,) = lerobot.read_dataset(rec.dataset)[1]
    assert ep["success"] and len(ep["actions"]) == 5 and (ep["columns"]["start_state"] == 7).all()
    _wait_for(port, lambda v: not v["connections"])
    assert modes_lib.MODES[int(ep["columns"]["mode"][0])] == "base"
