"""The steering page's server: a dropped connection is not reported as an error; others are."""


def test_a_dropped_connection_is_not_reported_and_other_errors_are(capsys):
  from soe_jax.steer import server

  srv = server.Server(("127.0.0.1", 0), server.BaseHTTPRequestHandler, bind_and_activate=False)
  for error, reported in ((BrokenPipeError(), False), (ConnectionResetError(), False), (RuntimeError("bug"), True)):
    try:
      raise error
    except Exception:
      srv.handle_error(None, ("127.0.0.1", 1))
    assert ("Traceback" in capsys.readouterr().err) == reported
  srv.server_close()
