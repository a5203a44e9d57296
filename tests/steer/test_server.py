"""The steering page's server: a dropped connection is not reported as an error; others are; and the
`steer` command's mistakes, each one line."""

import pytest

from soe_jax.commands import steer as steer_command
from soe_jax.steer import server


def test_a_dropped_connection_is_not_reported_but_others_are(capsys):
  """A connection the client dropped (broken pipe, reset) is not reported as an error; other errors are."""
  srv = server.Server(("127.0.0.1", 0), server.BaseHTTPRequestHandler, bind_and_activate=False)
  for error, reported in ((BrokenPipeError(), False), (ConnectionResetError(), False), (RuntimeError("bug"), True)):
    try:
      raise error
    except Exception:
      srv.handle_error(None, ("127.0.0.1", 1))
    assert ("Traceback" in capsys.readouterr().err) == reported
  srv.server_close()


@pytest.mark.parametrize(
  "argv, message",
  [
    ([], "--workdir is required"),
    (["--workdir=NOT_A_RUN"], "is not a run directory: config.json is missing"),
    (["--workdir=RUN", "--round=7"], "round 7 has no policy yet; the last with one is 2"),
    (["--workdir=RUN", "--port=70000"], "flag --port=70000"),
    (["--workdir=RUN", "extra"], "unexpected arguments: extra"),
  ],
)
def test_the_steer_command_says_what_is_wrong_in_one_line(smoke_run, tmp_path, capsys, argv, message):
  _, _, workdir, _ = smoke_run
  argv = [a.replace("RUN", workdir).replace("NOT_A_RUN", str(tmp_path)) for a in argv]
  steer_command.FLAGS.unparse_flags()
  with pytest.raises(SystemExit) as exit:
    steer_command.main(["python -m soe_jax steer", *argv])
  err = capsys.readouterr().err
  assert exit.value.code == 2 and err.startswith("error: ") and message in err and err.count("\n") == 1, err


def test_the_steer_commands_help_names_its_usage(capsys):
  with pytest.raises(SystemExit) as exit:
    steer_command.main(["python -m soe_jax steer", "--help"])
  out = capsys.readouterr().out
  assert exit.value.code == 0 and "python -m soe_jax steer --workdir=DIR" in out and "--port:" in out
