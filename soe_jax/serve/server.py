"""A policy served to a robot over openpi's protocol: a websocket, msgpack-numpy frames (`wire`).

On connect the server sends one frame, the metadata (`session.metadata`: the spec, the chunk's
timing); then each observation frame gets one reply frame (`session.Session.infer`) with
`server_timing` = {"infer_ms", "prev_total_ms"} added, so openpi-client's `WebsocketClientPolicy` and
`ActionChunkBroker(policy, action_horizon=Ta)` work unchanged. `GET /healthz` answers OK.

Who may connect: every handshake must carry the server's token as `Authorization: Api-Key <token>`
(openpi-client sends its `api_key` so), loopback included; a handshake with an `Origin` header not in
`origins` is refused (a browser page may open a websocket to a loopback port, and always says where it
comes from; robots' clients send none), as is one whose `Host` is not the server's address (DNS
rebinding; any Host when bound to every address). Frames over `max_size` bytes close the connection. A bad
request (not msgpack, a missing key, a wrong shape or dtype) or a chunk that is not fit to send (not
finite, outside the action box) gets one text frame saying what, as openpi's server sends its
errors, and that connection is closed; the others are served on. Each connection has its own
observation history and runs in its own thread.

The page (`page.py`, on its own port in the same process) reads the connections' state from
`sessions` and answers steering requests and labels: a steer request waits (`_choose`) until the page
picks a proposal, the timeout passes, or the robot disconnects.
"""

from __future__ import annotations

import http
import itertools
import logging
import threading
import time

import websockets
import websockets.sync.server as ws_server
from websockets.frames import CloseCode
from websockets.protocol import State

from soe_jax.data.spec import PolicySpec
from soe_jax.policies.agent import Agent
from soe_jax.runtime.access import Guard
from soe_jax.serve import modes as modes_lib
from soe_jax.serve import recorder as recorder_lib
from soe_jax.serve import session as session_lib
from soe_jax.serve import wire

log = logging.getLogger(__name__)


class StaleChoice(ValueError):
  """A choice for a steering request that is no longer waiting (timed out, answered, robot gone)."""


class PolicyServer:
  """`agent` served on `host`:`port` (0: any free port) to clients holding `token`, in `modes` (default
  `default_mode`), recording labelled episodes with `recorder` (None: not recording); a steer request
  waits `steer_timeout` seconds for the page's choice. Sampling keys: `seed`, `instance` (None: the
  microseconds since the epoch now) and an episode id counted over all connections (`session.Keys`)."""

  def __init__(self, agent: Agent, spec: PolicySpec, token: str, host: str = "127.0.0.1", port: int = 8000,
               seed: int = 0, origins: tuple[str, ...] = (), max_size: int = 16 << 20,
               modes: modes_lib.Modes | None = None, default_mode: str = "base",
               recorder: recorder_lib.Recorder | None = None, steer_timeout: float = 30.0,
               instance: int | None = None):  # fmt: skip
    self.guard = Guard(token)  # (a server without a token is refused here, before anything compiles)
    self.agent, self.spec, self.token, self.seed = agent, spec, token, seed
    self.keys = session_lib.Keys(seed, instance)  # shared by every connection: no two episodes share a key
    self.origins = tuple(origins)
    self.modes = modes if modes is not None else modes_lib.Modes(agent, spec)
    self.default_mode = self.modes.check(default_mode)
    self.recorder, self.steer_timeout = recorder, float(steer_timeout)
    self.metadata = session_lib.metadata(spec, agent, self.modes, default_mode)
    self.sessions: dict[str, session_lib.Session] = {}  # the connections open now, by name
    self._names = itertools.count(1)
    self._cond = threading.Condition()
    self._waiting: dict[tuple[str, str], int | None] = {}  # steering requests waiting for a choice
    self._gone: dict[tuple[str, str], str] = {}  # those that stopped waiting, and why
    session_lib.warm_up(agent, spec, self.modes)  # every compiled program before the port opens
    self._server = ws_server.serve(
      self._handle, host, port, compression=None, max_size=max_size, process_request=self._admit,
      server_header="soe_jax",
    )  # fmt: skip
    self.host, self.port = self._server.socket.getsockname()[:2]
    self.guard.bind(host, self.port)
    self._thread = None

  def _admit(self, connection: ws_server.ServerConnection, request) -> websockets.http11.Response | None:
    if request.path == "/healthz":
      return connection.respond(http.HTTPStatus.OK, "OK\n")
    host = request.headers.get("Host", "")
    if self.guard.hosts is not None and host not in self.guard.hosts:  # DNS rebinding
      log.warning("refused a handshake for host %s", host)
      return connection.respond(http.HTTPStatus.FORBIDDEN, f"host {host} is not this server's address\n")
    origin = request.headers.get("Origin")
    if origin is not None and origin not in self.origins:
      log.warning("refused a handshake from origin %s", origin)
      return connection.respond(http.HTTPStatus.FORBIDDEN, f"origin {origin} is not allowed\n")
    given = request.headers.get("Authorization", "")
    if not (given.startswith("Api-Key ") and self.guard.token_ok(given.removeprefix("Api-Key "))):
      log.warning("refused a handshake from %s without the token", connection.remote_address)
      return connection.respond(
        http.HTTPStatus.UNAUTHORIZED, "the server's token is required: Authorization: Api-Key <token>\n"
      )
    return None

  def _choose(self, session: session_lib.Session, steering: dict) -> int | None:
    """Wait for the page's choice of one of `steering`'s proposals: its index, or None when the timeout
    passes or the robot disconnects first."""
    key = (session.name, steering["request"])
    deadline = time.monotonic() + self.steer_timeout
    with self._cond:
      self._waiting[key] = None
      self._cond.notify_all()
      while self._waiting[key] is None:
        left = deadline - time.monotonic()
        if left <= 0 or not session.alive():
          break
        self._cond.wait(min(left, 0.1))
      choice = self._waiting.pop(key)
      if choice is None:
        self._gone[key] = (
          "the robot disconnected"
          if not session.alive()
          else (f"it timed out after {self.steer_timeout:g} s and the robot went on with the base path")
        )
    return choice

  def choose(self, connection: str, request: str, index) -> None:
    """The page's choice of proposal `index` for the waiting steering request `request` of `connection`."""
    key = (str(connection), str(request))
    with self._cond:
      if key not in self._waiting:
        why = self._gone.get(key)
        raise StaleChoice(f"steering request {request} of connection {connection} is not waiting: "
                          + (why or "there is no such request"))  # fmt: skip
      session = self.sessions.get(key[0])
      count = len(session.steering["proposals"]) if session is not None and session.steering else 0
      if isinstance(index, bool) or not isinstance(index, int) or not 0 <= index < count:
        raise StaleChoice(f"proposal {index!r}: choose one of 0 .. {count - 1}")
      self._waiting[key] = index
      self._cond.notify_all()

  def waiting(self) -> list[tuple[str, str]]:
    with self._cond:
      return [k for k, v in self._waiting.items() if v is None]

  def _handle(self, connection: ws_server.ServerConnection) -> None:
    name = f"c{next(self._names)}"
    session = session_lib.Session(self.agent, self.spec, self.keys, self.modes, self.default_mode, self._choose,
                                  self.recorder, name)  # fmt: skip
    session.alive = lambda: connection.state is State.OPEN
    self.sessions[name] = session
    try:
      self._serve_connection(connection, session)
    finally:
      session.closed = True
      if not session.ended:  # (kept while an ended episode awaits the page's label)
        self.sessions.pop(name, None)
      if session.log is not None:
        log.warning("%s disconnected in episode %d: not recorded (an episode is written only when labelled)",
                    name, session.log.number)  # fmt: skip

  def _serve_connection(self, connection: ws_server.ServerConnection, session: session_lib.Session) -> None:
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
