"""Cameras through the server: a camera of any size is brought to the policy's by resize-with-pad (the
aspect ratio kept, centred on black), the robot's helper sends every camera it has, the page shows them
all, and a recording keeps the fitted dataset's cameras under its feature names, with its robot type
and task, so it reads back like the dataset it continues."""

import io
import re
import threading

import jax
import ml_collections
import numpy as np
import pytest
import websockets.sync.client as ws_client
from PIL import Image

from soe_jax.data import lerobot
from soe_jax.data import spec as spec_lib
from soe_jax.data.spec import PolicySpec
from soe_jax.policies import agent as agent_lib
from soe_jax.policies import normalizer
from soe_jax.policies.agent import Agent
from soe_jax.policies.policy import policy_from_spec
from soe_jax.robot import config as robot_config
from soe_jax.robot import dataset as dataset_lib
from soe_jax.serve import client, page, recorder, session, wire
from soe_jax.serve.server import PolicyServer
from tests.serve.test_policy_server import SPEC, _agent
from tests.serve.test_robot_page import TOKEN, _request

STATE, FRONT, WRIST = "observation.state", "observation.images.front", "observation.images.wrist"
SIDE = "observation.images.side"  # a camera the fitted dataset does not have
STATE_NAMES = [f"{j}.pos" for j in ("x", "y", "z", "qx", "qy", "qz", "qw")]
ACTION_NAMES = ["x", "y", "z", "r11", "r12", "r13", "r21", "r22", "r23", "gripper"]
CAMERA = (24, 32)  # the robot's cameras (height, width)
IMAGE_SPEC = dict(SPEC, observations={STATE: SPEC["observations"]["state"],
                                      FRONT: {"shape": [84, 84, 3], "dtype": "uint8", "image": True}})  # fmt: skip


def _padded_reference(image: np.ndarray) -> np.ndarray:
  """A 216 x 288 image as the policy's 84 x 84, by hand: 63 x 84 (the aspect ratio kept), 10 rows of black
  above and 11 below."""
  out = np.zeros((84, 84, 3), np.uint8)
  out[10:73] = np.asarray(Image.fromarray(image).resize((84, 63), Image.BILINEAR))
  return out


def test_a_camera_of_any_size_is_padded_to_the_policy_s():
  spec = PolicySpec.from_dict(IMAGE_SPEC)
  rng = np.random.default_rng(0)
  camera = rng.integers(0, 256, (216, 288, 3), dtype=np.uint8)
  x = session.policy_input(spec, {STATE: np.zeros(7, np.float32), FRONT: camera})
  np.testing.assert_array_equal(x["images"][FRONT][0], _padded_reference(camera))
  # k observations since the last request: each padded alike
  stack = rng.integers(0, 256, (3, 216, 288, 3), dtype=np.uint8)
  observations, stacked = session.observations_of(spec, {STATE: np.zeros((3, 7), np.float32), FRONT: stack})
  assert stacked and [o[FRONT].shape for o in observations] == [(84, 84, 3)] * 3
  np.testing.assert_array_equal(observations[2][FRONT], _padded_reference(stack[2]))
  for bad, shape in [(camera.astype(np.float32), "float32 [216, 288, 3]"), (camera[..., :1], "uint8 [216, 288, 1]"),
                     (camera[:0], "uint8 [0, 288, 3]")]:  # fmt: skip
    with pytest.raises(
      session.RequestError,
      match=re.escape(f"image '{FRONT}' must be uint8 height x width x 3 (or k x that), got {shape}"),
    ):
      session.policy_input(spec, {STATE: np.zeros(7, np.float32), FRONT: bad})


@pytest.mark.slow
def test_the_server_serves_an_image_policy_a_216_by_288_camera():
  """Over the websocket: the metadata gives the policy's image size, and the reply to a 216 x 288 camera is the
  chunk the policy gives in-process for the padded reference image."""
  spec = PolicySpec.from_dict(IMAGE_SPEC)
  config = robot_config.config("smoke,image")
  config.policy.head = ml_collections.ConfigDict(dict(name="mlp", kwargs=dict(hidden=(32, 32))))
  config.policy.encoder.kwargs.cameras = spec.image_keys
  policy = policy_from_spec(config.policy, spec)
  rng = np.random.default_rng(1)
  norm = normalizer.fit(
    rng.normal(size=(50, 7)), rng.uniform(-0.3, 0.3, size=(50, 10)), action_box=spec.action_bounds()
  )
  agent = Agent(policy, policy.init(jax.random.key(0)), norm)
  server = PolicyServer(agent, spec, TOKEN, port=0, instance=0).start()
  state, camera = rng.uniform(-0.2, 0.2, 7).astype(np.float32), rng.integers(0, 256, (216, 288, 3), dtype=np.uint8)
  try:
    with ws_client.connect(f"ws://127.0.0.1:{server.port}", additional_headers={"Authorization": f"Api-Key {TOKEN}"},
                           max_size=None) as ws:  # fmt: skip
      meta = wire.unpackb(ws.recv())
      ws.send(wire.packb({STATE: state, FRONT: camera, "episode_start": True}))
      reply = wire.unpackb(ws.recv())
  finally:
    server.shutdown()
  assert meta["image_size"] == [84, 84]
  x = {"lowdim": state[None], "images": {FRONT: _padded_reference(camera)[None]}}
  history = agent_lib.initial_history(x, policy.n_obs_steps)
  expected = np.asarray(server.modes("base", agent, history, session.request_key(0, 0, 0, 0)))[0]
  np.testing.assert_allclose(reply["actions"], expected, atol=1e-6)


@pytest.fixture(scope="module")
def source(tmp_path_factory):
  """The dataset a low-dimensional policy was fitted on: a robot of type so101 with named state and action, two
  cameras (the front one a video, the wrist one PNG images) that the policy does not read, and one task."""
  rng = np.random.default_rng(2)
  episodes = [{"obs": {STATE: rng.normal(size=(5, 7)).astype(np.float32),
                       FRONT: rng.integers(0, 256, (5, *CAMERA, 3), dtype=np.uint8),
                       WRIST: rng.integers(0, 256, (5, *CAMERA, 3), dtype=np.uint8)},
               "actions": rng.normal(size=(5, 10)).astype(np.float32)} for _ in range(2)]  # fmt: skip
  root = str(tmp_path_factory.mktemp("source") / "demos")
  lerobot.write_dataset(root, episodes, fps=10, robot_type="so101", video_keys=[FRONT], task="stack the cups",
                        names={STATE: STATE_NAMES, "action": ACTION_NAMES})  # fmt: skip
  config = robot_config.config("smoke")
  config.dataset.observations = (STATE,)
  return root, config, dataset_lib.spec_of(root, config.dataset)


def test_the_spec_keeps_the_fitted_dataset_s_description(source, tmp_path):
  root, _, spec = source
  assert spec.source["robot_type"] == "so101" and spec.source["tasks"] == ["stack the cups"]
  assert spec.source["features"][STATE]["names"] == STATE_NAMES and spec.source["features"][WRIST]["dtype"] == "image"
  assert recorder.kept_keys(spec) == (STATE, FRONT, WRIST)
  assert "source" not in spec.to_dict() and spec == PolicySpec.from_dict(spec.to_dict())  # not the interface
  spec_lib.save(str(tmp_path), spec)
  assert spec_lib.load(str(tmp_path)).source == spec.source  # saved beside it


class _Policy:
  """openpi-client's `WebsocketClientPolicy` in miniature, keeping what it sent."""

  def __init__(self, ws):
    self.ws, self.sent = ws, []
    self.metadata = wire.unpackb(ws.recv())

  def get_server_metadata(self):
    return self.metadata

  def infer(self, obs):
    self.sent.append(obs)
    self.ws.send(wire.packb(obs))
    return wire.unpackb(self.ws.recv())


def test_every_camera_is_sent_shown_and_the_fitted_dataset_s_recorded(source, tmp_path):
  root, config, spec = source
  rec = recorder.Recorder(str(tmp_path / "rec"), spec)  # no task given: the fitted dataset's
  server = PolicyServer(_agent(spec), spec, TOKEN, port=0, recorder=rec).start()
  httpd = page.serve(server, "127.0.0.1", 0)
  threading.Thread(target=httpd.serve_forever, daemon=True).start()
  port = httpd.server_address[1]
  rng = np.random.default_rng(3)
  seen, shown = [], {}

  def observe():
    obs = {STATE: rng.uniform(-0.2, 0.2, 7).astype(np.float32), "observation.images.depth": np.zeros(CAMERA, np.uint16)}
    obs.update({k: rng.integers(0, 256, (*CAMERA, 3), dtype=np.uint8) for k in (FRONT, WRIST, SIDE)})
    seen.append(obs)
    return obs

  def act(_):
    if not shown:  # the page, while the episode is under way
      shown.update(view=_request(port, "GET", "/api/state")[1],
                   side=_request(port, "GET", f"/api/image?connection=c1&key={SIDE}")[1])  # fmt: skip

  try:
    with ws_client.connect(f"ws://127.0.0.1:{server.port}", additional_headers={"Authorization": f"Api-Key {TOKEN}"},
                           max_size=None) as ws:  # fmt: skip
      policy = _Policy(ws)
      runner = client.EpisodeRunner(policy=policy)
      out = runner.run_episode(observe, act, max_steps=10, label=lambda: "success")
  finally:
    httpd.shutdown()
    httpd.server_close()
    server.shutdown()
  assert out["written"]
  # The helper sends every camera (not the depth map), stacked with the observations since the last request.
  assert [sorted(k for k in s if k.startswith("observation.")) for s in policy.sent] == [
    [FRONT, SIDE, WRIST, STATE]
  ] * 3
  assert policy.sent[1][SIDE].shape == (8, *CAMERA, 3)
  assert policy.metadata["recorded_cameras"] == [FRONT, WRIST]
  # The page shows every camera the robot sends, the fitted dataset's or not.
  assert shown["view"]["connections"][0]["images"] == [FRONT, SIDE, WRIST]
  assert np.array_equal(np.asarray(Image.open(io.BytesIO(shown["side"]))), seen[0][SIDE])
  # The recording: the fitted dataset's cameras under their names, its robot type, feature names and task.
  info, (ep,) = lerobot.read_dataset(rec.dataset)
  assert info["robot_type"] == "so101" and ep["tasks"] == ["stack the cups"]
  assert info["features"][STATE]["names"] == STATE_NAMES and info["features"]["action"]["names"] == ACTION_NAMES
  assert (info["features"][FRONT]["dtype"], info["features"][WRIST]["dtype"]) == ("video", "image")  # as the source
  assert SIDE not in info["features"] and sorted(ep["obs"]) == [FRONT, WRIST, STATE]
  np.testing.assert_array_equal(ep["obs"][WRIST], np.stack([s[WRIST] for s in seen[:10]]))  # PNG: exact
  assert ep["obs"][FRONT].shape == (10, *CAMERA, 3)
  # A re-fit reads the recording as the policy's spec: the same interface.
  rec_spec, _ = dataset_lib.read(rec.dataset, config.dataset)
  assert rec_spec.to_dict() == spec.to_dict() and rec_spec.source["robot_type"] == "so101"


def test_an_episode_whose_cameras_differ_is_not_written(source, tmp_path):
  _, _, spec = source
  rec = recorder.Recorder(str(tmp_path / "rec"), spec, task="wipe the table")
  s = session.Session(_agent(spec), spec, recorder=rec)
  rng = np.random.default_rng(4)
  ta = s.agent.policy.n_action_steps

  def episode(cameras_since, label="success"):
    s.infer({STATE: np.zeros(7, np.float32), WRIST: np.zeros((*CAMERA, 3), np.uint8), "episode_start": True})
    since = {STATE: rng.normal(size=(ta, 7)).astype(np.float32), **cameras_since}
    return s.infer(dict(since, episode_end=True, label=label))["recorded"]

  wrist = {WRIST: np.zeros((ta, *CAMERA, 3), np.uint8)}
  assert episode(wrist)["written"]
  lost = episode({})  # the wrist camera came with the first observation only
  assert not lost["written"] and f"camera '{WRIST}' came with 1 of its {ta} observations" in lost["reason"]
  larger = episode({WRIST: np.zeros((ta, 48, 64, 3), np.uint8)})
  assert not larger["written"] and "of shapes [(24, 32, 3), (48, 64, 3)]" in larger["reason"]
  s.infer({STATE: np.zeros(7, np.float32), "episode_start": True})
  other = s.infer({STATE: rng.normal(size=(ta, 7)).astype(np.float32), "episode_end": True, "label": "success"})
  other = other["recorded"]
  assert not other["written"] and f"{{}} are not the recording's {{{WRIST}: 24 x 32 x 3}}" in other["reason"]
  info, eps = lerobot.read_dataset(rec.dataset)
  assert len(eps) == 1 and eps[0]["tasks"] == ["wipe the table"]  # the task given replaces the dataset's
  with pytest.raises(session.RequestError, match=rf"camera '{WRIST}' has shape \[24, 32, 3\]; beside the other"):
    s.infer({STATE: np.zeros((2, 7), np.float32), WRIST: np.zeros((*CAMERA, 3), np.uint8)})
