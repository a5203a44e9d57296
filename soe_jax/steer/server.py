"""The steering page: a small HTTP server (standard library) over one `SteeringSession`.

  GET  /                 the page
  GET  /api/state        the session's view (JSON)
  GET  /api/frame.png    the scene from the fixed camera
  POST /api/proposals    {"dim": i, "round": r}      proposals along dimension i
  POST /api/execute      {"id": "...", "round": r}   run one proposal
  POST /api/finish | /api/reset {"seed": s} | /api/save {"round": r}

The state lives in the server, so reloading the page shows the same episode. A bad request gets a
400 with {"error": message} and changes nothing. Requests are served one at a time on the serving
thread (the renderer's GL context belongs to the thread that made it).
"""

from __future__ import annotations

import json
import sys
import threading
from http.server import BaseHTTPRequestHandler, HTTPServer

from soe_jax.steer.session import SteeringError, SteeringSession

PAGE = """<!doctype html>
<html><head><meta charset="utf-8"><title>soe_jax steering</title>
<style>
 body { font-family: sans-serif; margin: 1em; }
 #scene { position: relative; display: inline-block; width: SIZEpx; height: SIZEpx; vertical-align: top; }
 #scene img, #scene svg { position: absolute; left: 0; top: 0; width: SIZEpx; height: SIZEpx; }
 #scene svg { pointer-events: none; }
 .dim, .prop, .act { margin: 2px; padding: 4px 8px; }
 .dim.chosen { font-weight: bold; background: #fc6; }
 #error { color: #b00; min-height: 1.2em; }
 #side { display: inline-block; vertical-align: top; margin-left: 1em; max-width: 420px; }
</style></head>
<body>
<h2>Steering <span id="title"></span></h2>
<div id="scene"><img id="frame" alt="scene"><svg id="overlay" viewBox="0 0 SIZE SIZE"></svg></div>
<div id="side">
 <div id="status"></div>
 <h3>Effective latent dimensions (SNR)</h3><div id="dims"></div>
 <h3>Proposals</h3><div id="props">choose a dimension</div>
 <h3>Episode</h3>
 <button class="act" id="finish">finish</button> <button class="act" id="save">save as steered</button>
 <button class="act" id="reset">reset</button>
 <div id="error"></div>
</div>
<script>
const COLORS = ["#e41a1c", "#377eb8", "#4daf4a", "#984ea3", "#ff7f00", "#a65628", "#f781bf", "#999999"];
let view = null;
async function call(path, body) {
  const opts = body === undefined ? {} : {method: "POST", headers: {"Content-Type": "application/json"},
                                          body: JSON.stringify(body)};
  const r = await fetch(path, opts);
  const data = await r.json();
  document.getElementById("error").textContent = r.ok ? "" : data.error;
  if (r.ok) render(data);
  return data;
}
function line(points, color, width, id) {
  const d = points.map((p, i) => (i ? "L" : "M") + p[0].toFixed(1) + " " + p[1].toFixed(1)).join(" ");
  return `<path ${id ? `id="path-${id}"` : ""} d="${d}" stroke="${color}" stroke-width="${width}" fill="none"/>`;
}
function render(v) {
  view = v;
  document.getElementById("title").textContent = `round ${v.round}`;
  document.getElementById("status").innerHTML =
    `step <span id="step">${v.step}</span> / ${v.episode_length}` + (v.success ? " &mdash; <b id='success'>success</b>" : "") +
    (v.finished ? " &mdash; episode over" : "") + ` &mdash; saved episodes: <span id="saved">${v.saved}</span>`;
  const img = document.getElementById("frame");
  img.src = "/api/frame.png?t=" + Date.now();
  document.getElementById("dims").innerHTML = v.dims.map(d =>
    `<button class="dim${d.dim === v.chosen_dim ? " chosen" : ""}" id="dim-${d.dim}" data-dim="${d.dim}">dim ${d.dim} (${d.snr_db} dB)</button>`).join("");
  document.querySelectorAll(".dim").forEach(b => b.onclick = () => call("/api/proposals", {dim: Number(b.dataset.dim), round: view.round}));
  document.getElementById("props").innerHTML = v.proposals.length ? v.proposals.map((p, i) =>
    `<button class="prop" id="proposal-${i}" data-id="${p.id}" style="border-color:${COLORS[i % 8]};color:${COLORS[i % 8]}">proposal ${i}</button>`).join("")
    : "choose a dimension";
  document.querySelectorAll(".prop").forEach(b => b.onclick = () => call("/api/execute", {id: b.dataset.id, round: view.round}));
  let svg = line(v.path, "#000", 2);
  v.proposals.forEach((p, i) => svg += line(p.path, COLORS[i % 8], 3, p.id));
  document.getElementById("overlay").innerHTML = svg;
}
document.getElementById("finish").onclick = () => call("/api/finish", {});
document.getElementById("save").onclick = () => call("/api/save", {round: view.round});
document.getElementById("reset").onclick = () => call("/api/reset", {seed: view.seed});
call("/api/state");
</script></body></html>
"""


def make_handler(session: SteeringSession):
  lock = threading.Lock()
  page = PAGE.replace("SIZE", str(session.image_size)).encode()

  class Handler(BaseHTTPRequestHandler):
    def log_message(self, fmt, *args):  # keep the console for the address and errors
      pass

    def _send(self, code: int, body: bytes, kind: str) -> None:
      self.send_response(code)
      self.send_header("Content-Type", kind)
      self.send_header("Content-Length", str(len(body)))
      self.send_header("Cache-Control", "no-store")
      self.end_headers()
      self.wfile.write(body)

    def _json(self, code: int, obj) -> None:
      self._send(code, json.dumps(obj).encode(), "application/json")

    def do_GET(self):
      path = self.path.split("?")[0]
      with lock:
        if path == "/":
          self._send(200, page, "text/html; charset=utf-8")
        elif path == "/api/state":
          self._json(200, session.view())
        elif path == "/api/frame.png":
          self._send(200, session.image_png(), "image/png")
        else:
          self._json(404, {"error": f"no page {path}"})

    def do_POST(self):
      path = self.path.split("?")[0]
      try:
        length = int(self.headers.get("Content-Length", 0))
        body = json.loads(self.rfile.read(length) or b"{}")
        if not isinstance(body, dict):
          raise SteeringError("the request body must be a JSON object")
      except (ValueError, json.JSONDecodeError) as e:
        return self._json(400, {"error": f"bad request body: {e}"})
      actions = {
        "/api/proposals": lambda: session.proposals(body.get("dim"), body.get("round")),
        "/api/execute": lambda: session.execute(body.get("id"), body.get("round")),
        "/api/finish": session.finish,
        "/api/reset": lambda: session.reset(int(body.get("seed", session.seed))),
        "/api/save": lambda: session.save(body.get("round")),
      }
      if path not in actions:
        return self._json(404, {"error": f"no action {path}; known: {', '.join(sorted(actions))}"})
      with lock:
        try:
          self._json(200, actions[path]())
        except (SteeringError, ValueError, TypeError) as e:
          self._json(400, {"error": str(e)})

  return Handler


class Server(HTTPServer):
  def handle_error(self, request, client_address) -> None:
    if isinstance(sys.exc_info()[1], (BrokenPipeError, ConnectionResetError)):
      return  # the page dropped the connection (a reload, a closed tab): nothing went wrong here
    super().handle_error(request, client_address)


def serve(session: SteeringSession, host: str = "127.0.0.1", port: int = 8765) -> HTTPServer:
  """The server, bound but not serving: call `serve_forever` (in a thread of its own if need be)."""
  return Server((host, port), make_handler(session))
