"""Who may talk to the servers: a non-loopback bind only when asked for; Host, Origin and token checks."""

import pytest

from soe_jax.runtime import access
from soe_jax.runtime.errors import UserError


def test_a_network_bind_needs_to_be_asked_for():
  assert access.check_bind("127.0.0.1", False) is None
  with pytest.raises(UserError, match="--host=0.0.0.0 is reachable from the network; add --remote"):
    access.check_bind("0.0.0.0", False)
  assert "reachable from the network" in access.check_bind("0.0.0.0", True)
  assert access.new_token({}) != access.new_token({}) and access.new_token({access.TOKEN_VARIABLE: "x"}) == "x"


def test_the_guard_refuses_strangers():
  guard = access.Guard("tok")
  guard.bind("127.0.0.1", 8001)
  ok = {"Host": "localhost:8001", "Authorization": "Api-Key tok"}
  assert guard.refusal(ok) is None and guard.refusal({"Host": "127.0.0.1:8001"}, query_token="tok") is None
  assert guard.refusal({**ok, "Host": "evil.example:8001"})[0] == 403
  assert guard.refusal({**ok, "Origin": "http://evil.example"})[0] == 403
  assert guard.refusal({**ok, "Origin": "http://127.0.0.1:8001"}) is None  # the page's own
  assert guard.refusal({"Host": "127.0.0.1:8001", "Authorization": "Api-Key nope"})[0] == 401
  anywhere = access.Guard("tok")
  anywhere.bind("0.0.0.0", 8001)  # every address: the Host cannot be checked, the token still is
  assert anywhere.refusal({"Host": "10.0.0.7:8001", "Authorization": "Api-Key tok"}) is None
  assert anywhere.refusal({"Host": "10.0.0.7:8001"})[0] == 401
  with pytest.raises(ValueError):
    access.Guard("")


def test_a_token_never_starts_with_a_dash(monkeypatch):
  """`--token VALUE` in the usual clients reads a value starting with `-` as another flag; token_urlsafe
  starts one token in 64 so."""
  assert not any(access.new_token({}).startswith("-") for _ in range(2000))
  drawn = iter(["-a1", "-b2", "c3"])
  monkeypatch.setattr(access.secrets, "token_urlsafe", lambda n: next(drawn))
  assert access.new_token({}) == "c3"
