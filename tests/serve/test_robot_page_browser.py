"""The robot's page in a real headless browser (Debian's chromium through Playwright): the robot's camera
image, the proposals' paths drawn from above and from the side, a click that sends a proposal to the
waiting robot, and a label button that writes the ended episode."""

import threading

import numpy as np

from soe_jax.data import lerobot
from soe_jax.serve import wire
from tests.serve.test_modes import _obs, served  # noqa: F401 (the module fixture)
from tests.serve.test_robot_page import TOKEN, _robot, running  # noqa: F401 (the fixture)
from tests.steer.test_page import CHROMIUM, pytestmark  # noqa: F401 (skipped without chromium)


def _camera(rng) -> np.ndarray:
  img = np.zeros((96, 128, 3), np.uint8)
  img[20:60, 30:90] = rng.integers(60, 255, 3, dtype=np.uint8)  # a coloured block on black
  return img


def test_the_robot_view_steers_and_labels(running):  # noqa: F811
  from playwright.sync_api import sync_playwright

  server, port, rec = running
  rng = np.random.default_rng(5)
  with _robot(server) as ws, sync_playwright() as p:
    browser = p.chromium.launch(executable_path=CHROMIUM, args=["--no-sandbox"])
    page = browser.new_page(viewport={"width": 1280, "height": 800})
    page.goto(f"http://127.0.0.1:{port}/?token={TOKEN}")
    page.wait_for_selector("#conn-c1")  # the robot, connected, before its first request
    replies = []
    first = dict(_obs(rng), episode_start=True, mode="steer", **{"observation.images.front": _camera(rng)})
    robot = threading.Thread(target=lambda: ws.send(wire.packb(first)) or replies.append(wire.unpackb(ws.recv())))
    robot.start()
    page.wait_for_selector("button.prop")
    assert page.locator("button.prop").count() == 4  # 2 dimensions x 2 proposals
    assert page.locator("#top-c1 .proposal-path").count() == 4 and page.locator("#side-c1 .proposal-path").count() == 4
    page.wait_for_function("document.querySelector('.cams img').naturalWidth === 128")  # the robot's camera
    assert "offered" in page.inner_text("#snr")
    page.click("button.prop >> nth=1")
    robot.join(10)
    assert replies[0]["steering"]["chosen"] == 1
    page.wait_for_selector("#top-c1 .trail")  # the chosen proposal, now the path the hand was sent along
    ws.send(wire.packb(dict(_obs(rng, 3), episode_end=True)))
    assert wire.unpackb(ws.recv())["recorded"]["awaiting_label"]
    page.wait_for_selector("button.lab")
    page.fill("#start-c1-0", "4")
    page.click("button.lab >> text=success")
    page.wait_for_function("document.getElementById('summary').textContent.includes('(1 written)')")
    browser.close()
  (ep,) = lerobot.read_dataset(rec.dataset)[1]
  assert ep["success"] and len(ep["actions"]) == 3 and (ep["columns"]["start_state"] == 4).all()
  np.testing.assert_allclose(ep["actions"], np.asarray(replies[0]["steering"]["proposals"][1], np.float32)[:3])
