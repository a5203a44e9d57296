"""The robot page's picture in the README (`docs/robot_page.png`, 1280x800): Lift's simulator as the robot.
Its scripted demonstrations written as a LeRobotDataset, a low-dim policy fitted on them with `fit`
(`configs/robot.py:cpu`, 8,000 steps), served with the page (steering along the two strongest dimensions, three
proposals each); the robot runs two base-path chunks,
sending its two cameras as well, then asks to be steered, and the picture is taken while the request
waits for a choice.

  python docs/robot_page_screenshot.py [--demos=10 --steps=8000 --out=docs/robot_page.png]

Needs Debian's chromium (see the README's test section); about 15 minutes on a 2-core CPU.
"""

from __future__ import annotations

import os
import tempfile
import threading

from absl import app, flags

flags.DEFINE_integer("demos", 10, "Scripted demonstrations of Lift to fit on.")
flags.DEFINE_integer("steps", 8000, "Fit steps (the cpu preset has 12,500; the picture was made with 8,000).")
flags.DEFINE_string("out", "docs/robot_page.png", "Where the picture goes.")
FLAGS = flags.FLAGS
TOKEN = "screenshot"


def main(argv):
  del argv
  import jax
  import numpy as np
  from playwright.sync_api import sync_playwright

  from soe_jax.data import export
  from soe_jax.data.episodes import EpisodeSet
  from soe_jax.envs import observations, panda
  from soe_jax.envs.registry import make_env
  from soe_jax.experts import collect
  from soe_jax.render.pool import Renderer
  from soe_jax.robot import config as robot_config
  from soe_jax.robot import run
  from soe_jax.serve import modes as modes_lib
  from soe_jax.serve import page, wire
  from soe_jax.serve.server import PolicyServer
  from soe_jax.train import checkpoint

  work = tempfile.mkdtemp(prefix="robot-page-")
  env = make_env("lift", backend="mujoco")
  demos = collect.demonstrations(env, FLAGS.demos, 0, progress=False)
  export.write_lerobot(os.path.join(work, "demos"), [EpisodeSet(demos, 0)], {"env_name": "lift"})
  keys = observations.POLICY_OBS_KEYS
  config = robot_config.config("cpu")
  config.dataset.update(path=os.path.join(work, "demos"), observations=tuple(f"observation.{k}" for k in keys))
  config.dataset.normalize.gripper = "identity"
  config.fit.num_steps = FLAGS.steps
  run.fit(config, os.path.join(work, "run"))
  ckpt = os.path.join(work, "run", "rounds", "0", "ckpt")
  loaded = checkpoint.load(ckpt)
  modes = modes_lib.Modes(loaded.agent, loaded.spec, modes_lib.Settings(max_dims=2), modes_lib.stored_snr(ckpt))
  server = PolicyServer(loaded.agent, loaded.spec, TOKEN, port=0, modes=modes, steer_timeout=600).start()
  httpd = page.serve(server, "127.0.0.1", 0)
  threading.Thread(target=httpd.serve_forever, daemon=True).start()

  renderer = Renderer(env.mj_model, ("agentview", panda.EYE_IN_HAND), 288, processes=1)
  step, state = jax.jit(env.step), jax.jit(env.reset)(jax.random.key(3))

  def request(mode: str, start: bool) -> dict:
    frames = renderer.render(np.asarray(state.pipeline_state.qpos))
    obs = {f"observation.{k}": np.asarray(state.obs[k], np.float32) for k in keys}
    obs.update({f"observation.images.{v}": frames[v] for v in frames}, mode=mode, episode_start=start)
    return obs

  import websockets.sync.client as ws_client

  def robot():
    nonlocal state
    with ws_client.connect(f"ws://127.0.0.1:{server.port}", additional_headers={"Authorization": f"Api-Key {TOKEN}"},
                           max_size=None) as ws:  # fmt: skip
      ws.recv()
      for i in range(3):
        ws.send(wire.packb(request("steer" if i == 2 else "base", i == 0)))
        for a in wire.unpackb(ws.recv())["actions"]:
          state = step(state, a)

  robot_thread = threading.Thread(target=robot, daemon=True)
  robot_thread.start()
  with sync_playwright() as p:
    browser = p.chromium.launch(executable_path="/usr/bin/chromium", args=["--no-sandbox"])
    shot = browser.new_page(viewport={"width": 1280, "height": 800})
    shot.goto(f"http://127.0.0.1:{httpd.server_address[1]}/?token={TOKEN}")
    shot.wait_for_selector("button.prop", timeout=600_000)
    shot.wait_for_function("[...document.querySelectorAll('.cams img')].every(i => i.naturalWidth > 0)")
    shot.screenshot(path=FLAGS.out)
    shot.click("button.prop >> nth=0")  # let the robot go on
    browser.close()
  robot_thread.join(60)
  renderer.close()
  httpd.shutdown()
  server.shutdown()
  print(f"-> {FLAGS.out}")


if __name__ == "__main__":
  app.run(main)
