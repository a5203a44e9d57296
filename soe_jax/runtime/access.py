"""Who may talk to the project's servers (the policy server, its page, the steering page): a random token
printed with the address and required on every request, loopback included; a `Host` that is the
server's own address (a page on another site can make a browser send requests to a loopback port under
a name that resolves there: DNS rebinding); an `Origin`, when a browser sends one, that is the server's
own; and an address other than loopback only when asked for, with a warning."""

from __future__ import annotations

import hmac
import os
import secrets

from soe_jax.runtime.errors import UserError

LOOPBACK = ("127.0.0.1", "localhost", "::1")
WILDCARD = ("0.0.0.0", "::", "")
TOKEN_VARIABLE = "SOE_JAX_SERVE_TOKEN"  # a fixed token instead of a random one (scripts, tests)


def new_token(environ: dict | None = None) -> str:
  """`SOE_JAX_SERVE_TOKEN`, or a random URL-safe token that does not start with `-` (which clients'
  `--token VALUE` would read as a flag)."""
  environ = os.environ if environ is None else environ
  if environ.get(TOKEN_VARIABLE):
    return environ[TOKEN_VARIABLE]
  token = secrets.token_urlsafe(24)
  while token.startswith("-"):  # (one in 64; drawn again, so every other token stays as likely)
    token = secrets.token_urlsafe(24)
  return token


def check_bind(host: str, remote: bool) -> str | None:
  """Refuse a non-loopback `host` unless `remote`; -> the warning to print when it is allowed."""
  if host in LOOPBACK:
    return None
  if not remote:
    raise UserError(f"--host={host} is reachable from the network; add --remote to serve there (only the token "
                    "keeps strangers out)")  # fmt: skip
  return f"warning: serving on {host}, reachable from the network; only the token keeps strangers out"


class Guard:
  """The checks of one server bound at `host`:`port` (`bind` once the port is known)."""

  def __init__(self, token: str):
    if not token:
      raise ValueError("a server needs a token")
    self.token = token
    self.hosts: set[str] | None = set()  # the Host values accepted (None: any, bound to every address)

  def bind(self, host: str, port: int) -> None:
    if host in WILDCARD:  # every address of the machine: its names are not known here
      self.hosts = None
      return
    names = {*LOOPBACK, host}
    self.hosts = {f"[{h}]:{port}" if ":" in h else f"{h}:{port}" for h in names}

  def origin_ok(self, origin: str | None) -> bool:
    if origin is None:
      return True
    site = origin.removeprefix("http://").removeprefix("https://")
    return site in self.hosts if self.hosts is not None else site.rsplit(":", 1)[0] not in ("", "null")

  def token_ok(self, given: str) -> bool:
    return hmac.compare_digest(given.encode(), self.token.encode())

  def refusal(self, headers, query_token: str = "") -> tuple[int, str] | None:
    """(status, message) for a request that must be refused, or None. The token comes as
    `Authorization: Api-Key T` (or, for a page's own address and images, `?token=T`)."""
    host = headers.get("Host", "")
    if self.hosts is not None and host not in self.hosts:
      return 403, f"host {host!r} is not this server's address"
    if not self.origin_ok(headers.get("Origin")):
      return 403, f"origin {headers.get('Origin')} is not this server's"
    given = headers.get("Authorization", "").removeprefix("Api-Key ") or query_token
    if not self.token_ok(given):
      return 401, "the server's token is required (open the address printed at start, with its ?token=...)"
    return None
