"""The robot's page: what the served robot sees, its steering proposals and its episodes' labels, in a
browser, on its own port in the policy server's process (one store: the server's sessions).

  GET  /?token=T            the page (it sends the token with every request it makes)
  GET  /api/state           the connections: episode, step, mode, latest low-dim observation, the
                            latest steering request (proposals' end-effector paths per arm), the
                            ended episodes awaiting a label; the SNR of the latent dimensions
  GET  /api/image?connection=c&key=k   the connection's latest camera image (PNG): the policy's
                            cameras and any other `observation.images.*` the robot sends
  POST /api/choose {"connection", "request", "index"}      pick a waiting steering request's proposal
  POST /api/label  {"connection", "episode", "label", "start_state"?}   label an ended episode

Who may ask: every request carries the server's token (`Authorization: Api-Key T`, or `?token=T` for
the page itself), loopback included; a request whose `Host` is not this server's address (DNS
rebinding) or whose `Origin` is not the page's own is refused before it is read. A bad request gets a
400 with {"error": one line} and changes nothing.
"""

from __future__ import annotations

import io
import json
import threading
import urllib.parse
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

import numpy as np
from PIL import Image

from soe_jax.runtime.access import Guard
from soe_jax.serve import session as session_lib
from soe_jax.serve.server import PolicyServer, StaleChoice

MAX_BODY = 1 << 16

PAGE = """<!doctype html>
<html><head><meta charset="utf-8"><title>soe_jax robot</title>
<style>
 body { font-family: sans-serif; margin: 12px 16px; color: #222; }
 h2 { margin: 0 0 6px 0; } h3 { margin: 8px 0 4px 0; font-size: 15px; }
 .help { font-size: 13px; color: #444; max-width: 1240px; margin: 4px 0 10px 0; line-height: 1.35; }
 .conn { display: flex; gap: 16px; align-items: flex-start; border-top: 1px solid #ccc; padding-top: 8px; }
 .cams img { width: 288px; display: block; margin-bottom: 4px; background: #eee; }
 .plot { border: 1px solid #bbb; background: #fafafa; }
 .prop { margin: 2px; padding: 4px 8px; border: 2px solid; background: #fff; font-weight: bold; }
 .lab { margin: 2px; padding: 4px 10px; } #error { color: #b00; min-height: 1.2em; }
 .note { font-size: 12px; color: #666; } table.snr td { padding: 0 6px; font-size: 12px; }
</style></head><body>
<h2>Robot <span id="summary"></span></h2>
<div class="help">Each connected robot shows its latest camera images, the path its hand was sent along this
episode (black) and, when it asks to be steered, a few proposals along the latent dimensions that carry
signal (coloured), from above (x, y) and from the side (x, z) in the robot's frame. Click a proposal to send
it; with no choice within the timeout the robot runs the base path. When an episode ends without a label,
label it <i>success</i>, <i>failure</i> or <i>discard</i> (discarded episodes are not written).</div>
<div id="error"></div><div id="conns">waiting for a robot&hellip;</div>
<h3>Latent dimensions (SNR over the fit's data)</h3><table class="snr" id="snr"></table>
<script>
const COLORS = ["#e41a1c", "#377eb8", "#4daf4a", "#984ea3", "#ff7f00", "#a65628", "#f781bf", "#999999",
                "#1b9e77", "#d95f02", "#7570b3", "#66a61e"];
const TOKEN = new URLSearchParams(location.search).get("token") || "";
const HEAD = {"Authorization": "Api-Key " + TOKEN};
const starts = {};  // start states typed, by connection-episode
async function call(path, body) {
  const r = await fetch(path, body === undefined ? {headers: HEAD} :
    {method: "POST", headers: {...HEAD, "Content-Type": "application/json"}, body: JSON.stringify(body)});
  const data = await r.json();
  document.getElementById("error").textContent = r.ok ? "" : data.error;
  return r.ok ? data : null;
}
function plot(id, paths, trails, a, b, label) {  // paths: [[colour, [[x,y,z],...], id]]; trails: per arm; axes a, b
  const pts = paths.flatMap(p => p[1]).concat(trails.flat());
  if (!pts.length) return `<svg class="plot" id="${id}" width="220" height="220"></svg>`;
  let lo = [Infinity, Infinity], hi = [-Infinity, -Infinity];
  pts.forEach(p => { [a, b].forEach((ax, i) => { lo[i] = Math.min(lo[i], p[ax]); hi[i] = Math.max(hi[i], p[ax]); }); });
  const span = Math.max(hi[0] - lo[0], hi[1] - lo[1], 0.02) * 1.15, mid = [(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2];
  const xy = p => [110 + (p[a] - mid[0]) / span * 200, 110 - (p[b] - mid[1]) / span * 200];
  const line = (ps, c, w, extra) => `<path ${extra || ""} d="${ps.map((p, i) => (i ? "L" : "M") + xy(p).map(v => v.toFixed(1)).join(" ")).join(" ")}" stroke="${c}" stroke-width="${w}" fill="none"/>`;
  let svg = `<text x="4" y="12" font-size="11">${label} (${(span * 100).toFixed(1)} cm across)</text>`;
  trails.forEach(t => { if (t.length) svg += line(t, "#000", 1.5, 'class="trail"'); });
  paths.forEach(([c, ps, pid]) => svg += line(ps, c, 3, `class="proposal-path" data-id="${pid}"`));
  return `<svg class="plot" id="${id}" width="220" height="220">${svg}</svg>`;
}
function render(v) {
  document.getElementById("summary").textContent = `${v.connections.length} connected` +
    (v.recording ? `, recording to ${v.recording} (${v.saved} written)` : ", not recording");
  document.getElementById("snr").innerHTML = (v.snr_db || []).map((s, i) =>
    `<tr><td>dim ${i}</td><td>${s.toFixed(1)} dB</td><td>${v.dims.includes(i) ? "offered" : ""}</td></tr>`).join("");
  document.getElementById("conns").innerHTML = v.connections.length ? v.connections.map(c => {
    const st = c.steering;
    let props = "", paths = [];
    if (st) {
      st.paths.forEach((arms_, i) => arms_.forEach(ps => paths.push([COLORS[i % COLORS.length], ps, i])));
      props = st.waiting ? st.paths.map((_, i) => `<button class="prop" data-conn="${c.name}" data-req="${st.request}" data-i="${i}"
        style="border-color:${COLORS[i % COLORS.length]}">${i} (dim ${st.dim_of[i]})</button>`).join("") :
        `<span class="note">request ${st.request}: ${st.chosen === null ? "no choice (base path)" : "sent proposal " + st.chosen}</span>`;
    }
    const labels = c.awaiting_label.map(e => `<div>episode ${e}: ` + ["success", "failure", "discard"].map(l =>
      `<button class="lab" data-conn="${c.name}" data-ep="${e}" data-label="${l}">${l}</button>`).join("") +
      ` start state <input size="3" class="start" id="start-${c.name}-${e}" value="${starts[c.name + "-" + e] || ""}"></div>`).join("");
    return `<div class="conn" id="conn-${c.name}"><div class="cams">${c.images.map(k =>
      `<img data-conn="${c.name}" data-key="${k}" alt="${k}">`).join("")}</div>
      <div>${plot("top-" + c.name, paths, c.trail, 0, 1, "from above: x, y")}</div>
      <div>${plot("side-" + c.name, paths, c.trail, 0, 2, "from the side: x, z")}</div>
      <div><b>${c.name}</b> ${c.closed ? "(disconnected)" : ""}<br>episode <span class="episode">${c.episode}</span>,
      request ${c.step}, mode <span class="mode">${c.mode}</span><h3>Proposals</h3>${props || "none asked"}
      <h3>Label</h3>${labels || "<span class='note'>no ended episode awaits a label</span>"}</div></div>`;
  }).join("") : "waiting for a robot&hellip;";
  document.querySelectorAll("button.prop").forEach(b => b.onclick = () => call("/api/choose",
    {connection: b.dataset.conn, request: b.dataset.req, index: Number(b.dataset.i)}).then(refresh));
  document.querySelectorAll("input.start").forEach(i => i.oninput = () => starts[i.id.slice(6)] = i.value);
  document.querySelectorAll("button.lab").forEach(b => b.onclick = () => {
    const s = document.getElementById(`start-${b.dataset.conn}-${b.dataset.ep}`).value.trim();
    const body = {connection: b.dataset.conn, episode: Number(b.dataset.ep), label: b.dataset.label};
    if (s) body.start_state = Number(s);
    call("/api/label", body).then(refresh);
  });
  document.querySelectorAll(".cams img").forEach(async img => {
    const r = await fetch(`/api/image?connection=${img.dataset.conn}&key=${encodeURIComponent(img.dataset.key)}`, {headers: HEAD});
    if (r.ok) img.src = URL.createObjectURL(await r.blob());
  });
}
let shown = "";  // redrawn only when the state changed, so a start state being typed is not wiped
async function refresh() {
  const v = await call("/api/state");
  if (v && JSON.stringify(v) !== shown) { shown = JSON.stringify(v); render(v); }
}
refresh(); setInterval(refresh, 1000);
</script></body></html>
"""


def _positions(spec, actions: np.ndarray) -> list:
  """(T, A) actions -> per arm its positions [[x, y, z], ...] (arms without a position left out)."""
  return [np.asarray(actions)[:, idx].round(5).tolist() for idx in spec.position_indices() if len(idx) == 3]


def state(server: PolicyServer) -> dict:
  """The page's view of every connection (JSON)."""
  out = []
  for name, s in list(server.sessions.items()):
    with s.lock:
      latest, steering, trail, cameras = s.latest, s.steering, list(s.trail), sorted(s.cameras)
      view = dict(name=name, episode=s.episode, step=s.step, mode=s.mode, closed=s.closed,
                  awaiting_label=sorted(s.ended))  # fmt: skip
    view["images"] = cameras
    view["lowdim"] = {k: np.asarray(latest[k]).round(5).tolist() for k in server.spec.lowdim_keys} if latest else {}
    view["trail"] = _positions(server.spec, np.asarray(trail)) if trail else []
    if steering is not None:
      view["steering"] = dict(
        request=steering["request"], dims=steering["dims"], dim_of=steering["dim_of"], chosen=steering["chosen"],
        timed_out=steering["timed_out"], waiting=(name, steering["request"]) in server.waiting(),
        paths=[_positions(server.spec, np.asarray(p)) for p in steering["proposals"]],
      )  # fmt: skip
    else:
      view["steering"] = None
    out.append(view)
  steer = server.modes.describe()["steer"]
  rec = server.recorder
  return dict(connections=out, snr_db=steer["snr_db"], dims=steer["dims"], timeout_s=server.steer_timeout,
              recording=rec.dataset if rec else None, saved=rec.saved if rec else 0)  # fmt: skip


class PageError(ValueError):
  pass


def _image_png(server: PolicyServer, query: dict) -> bytes:
  name, key = query.get("connection", [""])[0], query.get("key", [""])[0]
  s = server.sessions.get(name)
  if s is None:
    raise PageError(f"no connection {name!r}; connected: {sorted(server.sessions)}")
  with s.lock:
    image = s.cameras.get(key)
    known = sorted(s.cameras)
  if image is None:
    raise PageError(f"connection {name} has sent no camera {key!r}; its cameras: {known}")
  buf = io.BytesIO()
  Image.fromarray(np.asarray(image, np.uint8)).save(buf, format="PNG")
  return buf.getvalue()


def _post(server: PolicyServer, path: str, body: dict) -> dict:
  if not isinstance(body, dict):
    raise PageError("the body is a JSON object")
  name = body.get("connection")
  s = server.sessions.get(name) if isinstance(name, str) else None
  if s is None:
    raise PageError(f"no connection {name!r}; connected: {sorted(server.sessions)}")
  if path == "/api/choose":
    try:
      server.choose(name, body.get("request"), body.get("index"))
    except StaleChoice as e:
      raise PageError(str(e)) from None
    return dict(chosen=body["index"])
  episode = body.get("episode")
  if isinstance(episode, bool) or not isinstance(episode, int):
    raise PageError(f"episode must be a whole number, got {episode!r}")
  try:
    out = s.label_ended(episode, body.get("label"), body.get("start_state"))
  except session_lib.RequestError as e:
    raise PageError(str(e)) from None
  if s.closed and not s.ended:
    server.sessions.pop(name, None)
  return dict(episode=episode, **out)


def serve(server: PolicyServer, host: str = "127.0.0.1", port: int = 0) -> ThreadingHTTPServer:
  """The page for `server` on `host`:`port` (0: any free port); call serve_forever on the result."""
  guard = Guard(server.token)
  lock = threading.Lock()

  class Handler(BaseHTTPRequestHandler):
    def log_message(self, fmt, *args):  # quiet: the server's own log says what matters
      pass

    def _send(self, status: int, body: bytes, ctype: str = "application/json") -> None:
      self.send_response(status)
      self.send_header("Content-Type", ctype)
      self.send_header("Content-Length", str(len(body)))
      self.send_header("Cache-Control", "no-store")
      self.end_headers()
      self.wfile.write(body)

    def _error(self, status: int, message: str) -> None:
      self._send(status, json.dumps({"error": message}).encode())

    def _admitted(self, query: dict) -> bool:
      refused = guard.refusal(self.headers, query.get("token", [""])[0])
      if refused:
        self._error(*refused)
      return refused is None

    def do_GET(self):
      url = urllib.parse.urlsplit(self.path)
      query = urllib.parse.parse_qs(url.query)
      if not self._admitted(query):
        return
      try:
        if url.path == "/":
          self._send(200, PAGE.encode(), "text/html; charset=utf-8")
        elif url.path == "/api/state":
          self._send(200, json.dumps(state(server)).encode())
        elif url.path == "/api/image":
          self._send(200, _image_png(server, query), "image/png")
        else:
          self._error(404, f"no page {url.path}")
      except PageError as e:
        self._error(400, str(e))

    def do_POST(self):
      url = urllib.parse.urlsplit(self.path)
      if not self._admitted(urllib.parse.parse_qs(url.query)):
        return
      if url.path not in ("/api/choose", "/api/label"):
        return self._error(404, f"no endpoint {url.path}")
      try:
        length = int(self.headers.get("Content-Length", "0"))
        if not 0 < length <= MAX_BODY:
          raise PageError(f"a body of {length} bytes; between 1 and {MAX_BODY}")
        try:
          body = json.loads(self.rfile.read(length))
        except ValueError:
          raise PageError("the body is not JSON") from None
        with lock:
          self._send(200, json.dumps(_post(server, url.path, body)).encode())
      except PageError as e:
        self._error(400, str(e))

  httpd = ThreadingHTTPServer((host, port), Handler)
  httpd.daemon_threads = True
  guard.bind(host, httpd.server_address[1])
  return httpd
