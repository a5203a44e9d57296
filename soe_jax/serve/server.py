"""A policy served to a robot over openpi's protocol: a websocket, msgpack-numpy frames (`wire`).

On connect the server sends one frame, the metadata (`session.metadata`: the spec, the chunk's
timing); then each observation frame gets one reply frame (`session.Session.infer`) with
`server_timing` = {"infer_ms", "prev_total_ms"} added, so openpi-client's `WebsocketClientPolicy` and
`ActionChunkBroker(policy, action_horizon=Ta)` work unchanged. `GET /healthz` answers OK.

Who may connect: every handshake must carry the server's token as `Authorization: Api-Key <token>`
(openpi-client sends its `api_key` so), loopback included; a handshake with an `Origin` header not in
`origins` is refused (a browser page may open a websocket to a loopback port, and always says where it
comes from; robots' clients send none). Frames over `max_size` bytes close the connection. A bad
request (not msgpack, a missing key, a wrong shape or dtype) or a chunk that is not fit to send (not
finite, outside the action box) gets one text frame saying what, as openpi's server sends its
errors, and that connection is closed; the others are served on. Each connection has its own
observation history and runs in its own thread.
"""

from __future__ import annotations

import hmac
import http
import logging
import threading
import time

import websockets
import websockets.sync.server as ws_server
from websockets.frames import CloseCode

from soe_jax.data.spec import PolicySpec
from soe_jax.policies.agent import Agent
from soe_jax.serve import session as session_lib
from soe_jax.serve import wire

log = logging.getLogger(__name__)


class PolicyServer:
  """`agent` served on `host`:`port` (0: any free port) to clients holding `token`."""

  def __init__(self, agent: Agent, spec: PolicySpec, token: str, host: str = "127.0.0.1", port: int = 8000,
               seed: int = 0, origins: tuple[str, ...] = (), max_size: int = 16 << 20):  # fmt: skip
    if not token:
      raise ValueError("a policy server needs a token")
    self.agent, self.spec, self.token, self.seed = agent, spec, token, seed
    self.origins = tuple(origins)
    self.metadata = session_lib.metadata(spec, agent)
    session_lib.warm_up(agent, spec)  # every compiled program before the port opens
    self._server = ws_server.serve(
      self._handle, host, port, compression=None, max_size=max_size, process_request=self._admit,
      server_header="soe_jax",
    )  # fmt: skip
    self.host, self.port = self._server.socket.getsockname()[:2]
    self._thread = None

  def _admit(self, connection: ws_server.ServerConnection, request) -> websockets.http11.Response | None:
    if request.path == "/healthz":
      return connection.respond(http.HTTPStatus.OK, "OK\n")
    origin = request.headers.get("Origin")
    if origin is not None and origin not in self.origins:
      log.warning("refused a handshake from origin %s", origin)
      return connection.respond(http.HTTPStatus.FORBIDDEN, f"origin {origin} is not allowed\n")
    given = request.headers.get("Authorization", "")
    if not hmac.compare_digest(given.encode(), f"Api-Key {self.token}".encode()):
      log.warning("refused a handshake from %s without the token", connection.remote_address)
      return connection.respond(
        http.HTTPStatus.UNAUTHORIZED, "the server's token is required: Authorization: Api-Key <token>\n"
      )
    return None

  def _handle(self, connection: ws_server.ServerConnection) -> None:
    session = session_lib.Session(self.agent, self.spec, self.seed)
    connection.send(wire.packb(self.metadata))
    previous = None
    while True:
      try:
        frame = connection.recv()
      except websockets.ConnectionClosed:
        return
      start = time.monotonic()
      try:
        if isinstance(frame, str):
          raise session_lib.RequestError("frames are binary msgpack, not text")
        reply = session.infer(wire.unpackb(frame))
      except (wire.WireError, session_lib.RequestError, session_lib.PolicyError) as e:
        bad_request = not isinstance(e, session_lib.PolicyError)
        message = f"{'bad request' if bad_request else 'policy error'}: {e}"
        log.warning("%s: %s", connection.remote_address, message)
        try:
          connection.send(message)
          connection.close(CloseCode.POLICY_VIOLATION if bad_request else CloseCode.INTERNAL_ERROR, message[:120])
        except websockets.ConnectionClosed:
          pass
        return
      reply["server_timing"] = {"infer_ms": 1000 * (time.monotonic() - start)}
      if previous is not None:
        reply["server_timing"]["prev_total_ms"] = previous
      try:
        connection.send(wire.packb(reply))
      except websockets.ConnectionClosed:
        return
      previous = 1000 * (time.monotonic() - start)

  def serve_forever(self) -> None:
    self._server.serve_forever()

  def start(self) -> PolicyServer:
    """Serve in a background thread (tests, and a process that does more)."""
    self._thread = threading.Thread(target=self._server.serve_forever, daemon=True)
    self._thread.start()
    return self

  def shutdown(self) -> None:
    self._server.shutdown()
    if self._thread is not None:
      self._thread.join()
