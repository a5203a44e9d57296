"""The steering page: a small HTTP server (standard library) over one `SteeringSession`.

  GET  /                 the page
  GET  /api/state        the session's view (JSON)
  GET  /api/frame.png    the scene from the fixed camera
  GET  /api/hand.png     the scene from the wrist camera (the in-hand view)
  POST /api/proposals    {"dim": i, "round": r}      proposals along dimension i
  POST /api/execute      {"id": "...", "round": r}   run one proposal
  POST /api/finish | /api/reset {"seed": s} | /api/save {"round": r}

The state lives in the server, so reloading the page shows the same episode. A bad request gets a
400 with {"error": message} and changes nothing. Requests are served one at a time. Every request
carries the token printed with the address (`?token=` on the page's address; the page sends it on),
and is refused unless its `Host` is the server's address and its `Origin`, if any, the page's own
(`runtime/access.py`): steered episodes become training data.
"""

from __future__ import annotations

import json
import sys
import threading
import urllib.parse
from collections.abc import Callable
from http.server import BaseHTTPRequestHandler, HTTPServer

from soe_jax.envs import panda
from soe_jax.runtime import access
from soe_jax.runtime.access import Guard
from soe_jax.runtime.errors import UserError
from soe_jax.steer.session import SteeringError, SteeringSession

PAGE = """<!doctype html>
<html><head><meta charset="utf-8"><title>soe_jax steering</title>
<style>
 body { font-family: sans-serif; margin: 12px 16px; color: #222; }
 h2 { margin: 0 0 4px 0; } h3 { margin: 6px 0; font-size: 15px; }
 .help { font-size: 13px; color: #444; max-width: 1240px; margin: 4px 0 10px 0; line-height: 1.35; }
 #panels { display: flex; gap: 18px; align-items: flex-start; }
 #scene { position: relative; width: SIZEpx; height: SIZEpx; background: #eee; flex: none; }
 #scene img, #scene svg { position: absolute; left: 0; top: 0; width: SIZEpx; height: SIZEpx; }
 #scene svg { pointer-events: none; }
 #placeholder { position: absolute; top: 45%; width: 100%; text-align: center; color: #777; }
 .panel { width: 380px; flex: none; }
 .dim, .prop, .act { margin: 2px; padding: 4px 8px; }
 .dim.chosen { font-weight: bold; background: #fc6; }
 .prop { border: 2px solid; background: #fff; font-weight: bold; }
 #chart text { font-size: 11px; } #chart .row.offered { cursor: pointer; }
 #error { color: #b00; min-height: 1.2em; } #saved-note { color: #060; min-height: 1.2em; }
 .note { font-size: 12px; color: #666; }
</style></head>
<body>
<h2>Steering <span id="title"></span></h2>
<div class="help"><b>How to steer.</b> The policy's latent has a few dimensions that carry signal about the
scene (their SNR over the demonstrations is above the dashed threshold line); the others carry none and
are not offered. <b>1.</b> Choose a dimension: a few diverse proposals along it are drawn over the scene,
each the path the hand (each hand, on two arms) would take over the next <span id="chunk"></span> actions (the black path is the
hand's so far). <b>2.</b> Click a proposal to execute it, then choose again. The episode ends with
success, at the step limit, or when you press <i>finish</i>. <b>3.</b> <i>Save</i> adds the finished
episode to the run's data; the next round's fit takes <span id="used"></span> steered episodes
(<code>rounds.steered</code>).</div>
<div id="panels">
 <div id="scene"><div id="placeholder">rendering the scene&hellip;</div>
  <img id="frame" alt="scene"><svg id="overlay" viewBox="0 0 SIZE SIZE"></svg></div>
 <div class="panel"><h3>In-hand view</h3><img id="hand" alt="in-hand view" width="192" height="192"></div>
 <div class="panel">
  <h3>Latent dimensions: signal-to-noise ratio</h3>
  <svg id="chart" width="380" height="10"></svg>
  <div id="dims"></div><div class="note" id="dims-note"></div>
 </div>
 <div class="panel">
  <div id="status">loading&hellip;</div>
  <h3>Proposals <span id="along"></span></h3><div id="props">choose a dimension</div>
  <h3>Episode</h3>
  <button class="act" id="finish">finish</button> <button class="act" id="save">save as steered</button>
  <button class="act" id="reset">reset</button>
  <div id="error"></div><div id="saved-note"></div>
 </div>
</div>
<script>
const COLORS = ["#e41a1c", "#377eb8", "#4daf4a", "#984ea3", "#ff7f00", "#a65628", "#f781bf", "#999999"];
let view = null;
const TOKEN = new URLSearchParams(location.search).get("token") || "";
async function call(path, body) {
  const opts = body === undefined ? {} : {method: "POST", headers: {"Content-Type": "application/json"},
                                          body: JSON.stringify(body)};
  opts.headers = {...(opts.headers || {}), "Authorization": "Api-Key " + TOKEN};
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
function chart(v) {  // one bar per latent dimension, from the threshold; the offered ones clickable
  const rowH = 17, top = 16, left = 46, width = 210, vals = v.snr.map(d => d.snr_db);
  const lo = Math.min(v.threshold_db - 5, ...vals), hi = Math.max(v.threshold_db + 5, ...vals);
  const x = s => left + (s - lo) / (hi - lo) * width, t = x(v.threshold_db);
  let svg = `<text x="${t}" y="11" text-anchor="middle" fill="#b00">threshold ${v.threshold_db} dB</text>`;
  v.snr.forEach((d, i) => {
    const y = top + i * rowH, x0 = Math.min(t, x(d.snr_db)), w = Math.max(1, Math.abs(x(d.snr_db) - t));
    const fill = d.offered ? (d.dim === v.chosen_dim ? "#f90" : "#377eb8") : "#ccc";
    svg += `<g class="row${d.offered ? " offered" : " below"}" data-dim="${d.dim}">` +
      `<rect x="0" y="${y}" width="380" height="${rowH}" fill="transparent"/>` +
      `<text x="${left - 6}" y="${y + 12}" text-anchor="end">dim ${d.dim}</text>` +
      `<rect class="bar" x="${x0}" y="${y + 2}" width="${w}" height="${rowH - 4}" fill="${fill}"/>` +
      `<text x="${left + width + 6}" y="${y + 12}" fill="${d.offered ? "#222" : "#999"}">${d.snr_db.toFixed(1)} dB` +
      `${d.offered ? "" : " (no signal)"}</text></g>`;
  });
  const h = top + v.snr.length * rowH + 4;
  svg += `<line id="threshold" x1="${t}" x2="${t}" y1="14" y2="${h}" stroke="#b00" stroke-dasharray="4 3"/>`;
  const el = document.getElementById("chart");
  el.setAttribute("height", h);
  el.innerHTML = svg;
  el.querySelectorAll(".row.offered").forEach(g => g.onclick = () => choose(Number(g.dataset.dim)));
}
function choose(dim) { call("/api/proposals", {dim: dim, round: view.round}); }
function render(v) {
  view = v;
  document.getElementById("title").textContent = `round ${v.round}`;
  document.getElementById("chunk").textContent = v.steps_per_proposal;
  document.getElementById("used").textContent = v.used_in_fit === "all" ? "all" : "only the successful";
  document.getElementById("status").innerHTML =
    `step <span id="step">${v.step}</span> / ${v.episode_length}` + (v.success ? " &mdash; <b id='success'>success</b>" : "") +
    (v.finished ? " &mdash; episode over" : "") + ` &mdash; saved episodes: <span id="saved">${v.saved}</span>`;
  const q = `?t=${Date.now()}&token=${encodeURIComponent(TOKEN)}`;
  document.getElementById("frame").src = "/api/frame.png" + q;
  document.getElementById("hand").src = "/api/hand.png" + q;
  chart(v);
  document.getElementById("dims").innerHTML = v.dims.map(d =>
    `<button class="dim${d.dim === v.chosen_dim ? " chosen" : ""}" id="dim-${d.dim}" data-dim="${d.dim}">dim ${d.dim} (${d.snr_db} dB)</button>`).join("");
  document.querySelectorAll(".dim").forEach(b => b.onclick = () => choose(Number(b.dataset.dim)));
  document.getElementById("dims-note").textContent = v.none_above_threshold
    ? "No dimension is above the threshold: the strongest is offered, but it carries little signal." : "";
  document.getElementById("along").textContent = v.chosen_dim === null ? "" : `along dim ${v.chosen_dim}`;
  document.getElementById("props").innerHTML = v.proposals.length ? v.proposals.map((p, i) =>
    `<button class="prop" id="proposal-${i}" data-id="${p.id}" style="border-color:${COLORS[i % 8]};color:${COLORS[i % 8]}">proposal ${i}</button>`).join("")
    : (v.finished ? "the episode is over: save it or reset" : "choose a dimension");
  document.querySelectorAll(".prop").forEach(b => b.onclick = () => call("/api/execute", {id: b.dataset.id, round: view.round}));
  document.getElementById("save").disabled = !(v.finished && v.step > 0);
  const s = v.last_saved;
  document.getElementById("saved-note").textContent = s === null ? "" : `saved the last episode (${s.success ?
    "success" : "not successful"}): ${s.used ? "the next fit takes it" : "kept on disk, the next fit leaves it out"}`;
  let svg = v.paths.map(p => line(p, "#000", 2)).join("");  // one path per arm
  v.proposals.forEach((p, i) => p.paths.forEach((q, k) => svg += line(q, COLORS[i % 8], 3, k ? "" : p.id)));
  document.getElementById("overlay").innerHTML = svg;
}
document.getElementById("frame").onload = () => {  // the page is ready once the scene is drawn
  document.getElementById("placeholder").style.display = "none";
  document.body.dataset.ready = "true";
};
document.getElementById("finish").onclick = () => call("/api/finish", {});
document.getElementById("save").onclick = () => call("/api/save", {round: view.round});
document.getElementById("reset").onclick = () => call("/api/reset", {seed: view.seed});
call("/api/state");
</script></body></html>
"""


def make_handler(session: SteeringSession, guard: Guard):
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

    def _admitted(self) -> bool:
      query = urllib.parse.parse_qs(urllib.parse.urlsplit(self.path).query)
      refused = guard.refusal(self.headers, query.get("token", [""])[0])
      if refused:
        self._json(refused[0], {"error": refused[1]})
      return refused is None

    def do_GET(self):
      path = self.path.split("?")[0]
      if not self._admitted():
        return
      with lock:
        if path == "/":
          self._send(200, page, "text/html; charset=utf-8")
        elif path == "/api/state":
          self._json(200, session.view())
        elif path == "/api/frame.png":
          self._send(200, session.image_png(), "image/png")
        elif path == "/api/hand.png":
          self._send(200, session.image_png(panda.EYE_IN_HAND), "image/png")
        else:
          self._json(404, {"error": f"no page {path}"})

    def do_POST(self):
      path = self.path.split("?")[0]
      if not self._admitted():
        return
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


def serve(session: SteeringSession, host: str = "127.0.0.1", port: int = 8765, token: str = "") -> HTTPServer:
  """The server for clients holding `token`, bound but not serving: call `serve_forever` (in a thread of
  its own if need be)."""
  guard = Guard(token)
  httpd = Server((host, port), make_handler(session, guard))
  guard.bind(host, httpd.server_address[1])
  return httpd


def run(
  workdir: str,
  r: int | None = None,
  seed: int = 0,
  host: str = "127.0.0.1",
  port: int = 8765,
  ready: Callable[[SteeringSession, str], None] = lambda session, address: None,
) -> None:
  """Serve the steering page of round r's policy (default: the last round's) of the run in `workdir`
  until Ctrl-C: `ready(session, address)` once the policy is compiled and the first frame drawn."""
  session = SteeringSession(workdir, r, seed)
  token = access.new_token()
  try:
    try:
      httpd = serve(session, host, port, token)
    except OSError as e:
      raise UserError(f"cannot serve at {host}:{port}: {e.strerror or e}") from None
    try:
      session.warm()  # compiled and first frame rendered before the address is given
      ready(session, f"http://{host}:{httpd.server_address[1]}/?token={token}")
      httpd.serve_forever()
    except KeyboardInterrupt:
      pass  # the way to stop it
    finally:
      httpd.server_close()
  finally:
    session.close()
