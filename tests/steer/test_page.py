"""The steering page in a real headless browser (Debian's chromium through Playwright): choose a
dimension, click a proposal, see the state change, save, find the steered episode on disk; bad
requests get a clear error and change nothing."""

import json
import os
import threading
import urllib.error
import urllib.request

import pytest

CHROMIUM = "/usr/bin/chromium"
TOKEN = "steering-token"
# .ci/run installs both with apt-get; elsewhere the test says what is missing.
pytestmark = pytest.mark.skipif(
  not os.path.exists(CHROMIUM)
  or not any(
    os.path.exists(os.path.join(d, "libEGL_mesa.so.0")) for d in ("/usr/lib/x86_64-linux-gnu", "/usr/lib64", "/usr/lib")
  ),
  reason="needs Debian's chromium and Mesa's EGL: apt-get install chromium libegl1 libegl-mesa0 libgl1-mesa-dri",
)


@pytest.fixture(scope="module")
def page_server(smoke_run):
  from soe_jax.steer import server, session

  _, _, workdir, _ = smoke_run
  s = session.SteeringSession(workdir)
  httpd = server.serve(s, "127.0.0.1", 0, TOKEN)
  thread = threading.Thread(target=httpd.serve_forever, daemon=True)
  thread.start()
  yield f"http://127.0.0.1:{httpd.server_address[1]}", s, workdir
  httpd.shutdown()
  httpd.server_close()
  s.close()


def _mapped(name: str) -> bool:
  with open("/proc/self/maps") as f:
    return any(name in line for line in f)


def _get(url):
  req = urllib.request.Request(url, headers={"Authorization": f"Api-Key {TOKEN}"})
  with urllib.request.urlopen(req) as r:
    return json.load(r)


def _post(url, body, headers=None):
  headers = {"Content-Type": "application/json", "Authorization": f"Api-Key {TOKEN}", **(headers or {})}
  req = urllib.request.Request(url, json.dumps(body).encode(), headers)
  try:
    with urllib.request.urlopen(req) as r:
      return r.status, json.load(r)
  except urllib.error.HTTPError as e:
    return e.code, json.load(e)


def test_steer_a_proposal_and_save_it_from_the_browser(page_server):
  from playwright.sync_api import sync_playwright

  from soe_jax.data import hdf5

  url, session, workdir = page_server
  path = session.run.steered_path(session.round)
  assert not os.path.exists(path)
  with sync_playwright() as p:
    browser = p.chromium.launch(executable_path=CHROMIUM, args=["--no-sandbox"])
    page = browser.new_page()
    page.goto(f"{url}/?token={TOKEN}")
    page.wait_for_selector("body[data-ready=true]")  # the first frame is drawn
    assert page.inner_text("#step") == "0" and not page.is_visible("#placeholder")
    # The in-hand view beside the scene, drawn at the page's size.
    page.wait_for_function(f"document.getElementById('hand').naturalWidth === {session.image_size}")
    assert "How to steer" in page.inner_text(".help")
    latent = len(session.snr)  # one bar per latent dimension, the threshold drawn, the rest marked
    assert page.locator("#chart .row").count() == latent and page.locator("#threshold").count() == 1
    below = page.locator("#chart .row.below")
    assert below.count() == latent - len(session.dims) and page.locator(".dim").count() == len(session.dims)
    if below.count():
      assert "no signal" in below.nth(0).text_content()
    page.click(".dim >> nth=0")
    page.wait_for_selector("#proposal-0")
    assert page.locator(".prop").count() == session.steer.num_choices
    assert page.locator("#overlay path").count() == 1 + session.steer.num_choices  # paths drawn
    page.click("#proposal-0")
    page.wait_for_function("document.getElementById('step').textContent !== '0'")
    steps = int(page.inner_text("#step"))
    assert 1 <= steps <= session.policy.n_action_steps
    page.reload()  # the state lives in the server
    page.wait_for_selector(".dim")
    assert int(page.inner_text("#step")) == steps
    assert page.is_disabled("#save")  # not before the episode is over
    page.click("#finish")
    page.click("#save")
    page.wait_for_function("document.getElementById('saved').textContent === '1'")
    assert "leaves it out" in page.inner_text("#saved-note") or session.success
    assert page.inner_text("#step") == "0"  # a fresh episode after saving
    browser.close()
  # The frames were drawn by a child process: Mesa's LLVM never entered this one, which compiles XLA.
  assert session.frames.started and not _mapped("libLLVM")
  episodes, env_args = hdf5.read_episodes(path)
  assert len(episodes) == 1 and episodes[0]["actions"].shape == (steps, 10)
  assert episodes[0]["success"] is False  # a few steps of a smoke policy do not lift the cube
  assert env_args["soe_jax"]["steered"] is True


def test_nonsense_requests_are_refused_and_change_nothing(page_server):
  url, session, workdir = page_server
  before = _get(url + "/api/state")
  for action, body, message in [
    ("/api/execute", {"id": "7-7-7", "round": session.round}, "no proposals yet"),
    ("/api/proposals", {"dim": 999, "round": session.round}, "not an effective dimension"),
    ("/api/proposals", {"dim": session.dims[0], "round": session.round + 5}, "not round"),
    ("/api/save", {"round": session.round}, "nothing to save"),
    ("/api/launch", {}, "no action"),
  ]:
    code, data = _post(url + action, body)
    assert code in (400, 404) and message in data["error"], (action, data)
  code, props = _post(url + "/api/proposals", {"dim": session.dims[0], "round": session.round})
  assert code == 200
  code, data = _post(url + "/api/execute", {"id": "0-0-99", "round": session.round})
  assert code == 400 and "unknown proposal" in data["error"]
  after = _get(url + "/api/state")
  assert after["step"] == before["step"] and after["saved"] == before["saved"]
  code, data = _post(url + "/api/execute", {"id": props["proposals"][0]["id"], "round": session.round})
  assert code == 200 and data["step"] > 0 and not data["finished"]
  code, data = _post(url + "/api/save", {"round": session.round})  # an unfinished episode
  assert code == 400 and "not over" in data["error"]
  assert _get(url + "/api/state")["saved"] == before["saved"]


def test_strangers_are_refused_and_change_nothing(page_server):
  """The trap a cross-site page could spring: a plain-text POST /api/save from a foreign origin, a request
  under a foreign Host (DNS rebinding), or none with the token: each refused before it is read."""
  url, session, workdir = page_server
  before = _get(url + "/api/state")
  for headers, code in [
    ({"Authorization": ""}, 401),
    ({"Authorization": "Api-Key wrong"}, 401),
    ({"Origin": "http://evil.example", "Content-Type": "text/plain"}, 403),
    ({"Host": "evil.example:80"}, 403),
  ]:
    status, data = _post(url + "/api/save", {"round": session.round}, headers)
    assert status == code and "error" in data, (headers, data)
  req = urllib.request.Request(url + "/api/state")  # no token at all
  with pytest.raises(urllib.error.HTTPError, match="401"):
    urllib.request.urlopen(req)
  assert _get(url + "/api/state")["saved"] == before["saved"]
