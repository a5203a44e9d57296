"""The steering page's picture in the README (`docs/steering.png`, 1280x800), taken in headless chromium
after the first frame: one proposal executed, then the proposals along the strongest dimension.

  python docs/steering_screenshot.py --workdir=runs/square-soe-seed0 [--round=0]

Needs Debian's chromium (see the README's test section)."""

from __future__ import annotations

import threading

from absl import flags

from soe_jax.runtime import cli

flags.DEFINE_string("workdir", None, "A run directory written by python -m soe_jax run.", required=True)
flags.DEFINE_integer("round", None, "The round whose policy to steer (default: the last finished).")
flags.DEFINE_string("out", "docs/steering.png", "Where the picture goes.")
flags.DEFINE_integer("seed", 0, "Start state of the episode.")
FLAGS = flags.FLAGS


def main(argv):
  from soe_jax.steer import server, session

  s = session.SteeringSession(FLAGS.workdir, FLAGS.round, FLAGS.seed)
  s.warm()
  httpd = server.serve(s, "127.0.0.1", 0, "screenshot")
  url = f"http://127.0.0.1:{httpd.server_address[1]}/?token=screenshot"
  failed = []

  def shoot():  # the browser on a thread of its own: the server stays on this one
    from playwright.sync_api import sync_playwright

    try:
      with sync_playwright() as p:
        browser = p.chromium.launch(executable_path="/usr/bin/chromium", args=["--no-sandbox"])
        page = browser.new_page(viewport={"width": 1280, "height": 800})
        page.goto(url)
        page.wait_for_selector("body[data-ready=true]", timeout=600_000)
        page.click(".dim >> nth=0")
        page.wait_for_selector("#proposal-0", timeout=600_000)
        page.click("#proposal-0")
        page.wait_for_function("document.getElementById('step').textContent !== '0'", timeout=600_000)
        page.click(".dim >> nth=0")
        page.wait_for_selector("#proposal-0", timeout=600_000)
        page.wait_for_function("document.getElementById('frame').complete")
        page.screenshot(path=FLAGS.out)
        browser.close()
    except Exception as e:
      failed.append(e)
    finally:
      httpd.shutdown()

  threading.Thread(target=shoot).start()
  httpd.serve_forever()
  httpd.server_close()
  s.close()
  if failed:
    raise failed[0]
  print(f"{FLAGS.out}: round {s.round} of {FLAGS.workdir}, {len(s.dims)} dimensions offered")


if __name__ == "__main__":
  cli.run(main)
