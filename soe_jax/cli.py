"""What every command shares: a quiet start (MJX's two lines about the optional warp, absl's INFO
lines about absent accelerators), a `UserError` as one line on stderr with exit status 2 (anything
else keeps its traceback), SIGTERM handled as Ctrl-C, and Ctrl-C as a line on stderr with exit
status 130."""

from __future__ import annotations

import contextlib
import io
import sys
from collections.abc import Callable
from typing import NoReturn

from absl import app, logging

from soe_jax import interrupt
from soe_jax.errors import UserError


def fail(message: str) -> NoReturn:
  print(f"error: {message}", file=sys.stderr, flush=True)
  sys.exit(2)


def run(
  main: Callable[[list[str]], None], flags_parser=None, interrupted: str = "interrupted", mjx: bool = True
) -> None:
  """`absl.app.run(main)` with the above; `interrupted` is what Ctrl-C prints (a command that saves
  its work says where, and how to go on); `mjx`: the command may import MJX (which is then imported
  here, quietly)."""

  def wrapped(argv):
    logging.set_verbosity(logging.WARNING)
    interrupt.terminate_as_interrupt()
    try:
      main(argv)
    except UserError as e:
      fail(str(e))
    except KeyboardInterrupt:
      print(f"\n{interrupted}", file=sys.stderr, flush=True)
      sys.exit(130)

  if mjx:
    with contextlib.redirect_stdout(io.StringIO()):  # MJX prints that the optional warp is missing
      import mujoco.mjx  # noqa: F401
  app.run(wrapped, flags_parser=flags_parser or app.parse_flags_with_usage)


def config_file(argv: list[str], flag) -> tuple[str, dict]:
  """For a command of one `--config=configs/<task>.py[:PRESETS]` flag (`flag`, e.g. `FLAGS["config"]`)
  and no positional arguments: the config file's spec and the `--config.a.b=v` overrides, with the
  persistent compilation cache turned on."""
  from ml_collections import config_flags

  from soe_jax import compile_cache

  if len(argv) > 1:
    raise app.UsageError(f"unexpected arguments: {argv[1:]}")
  if flag.value is None:
    raise app.UsageError("--config=configs/<task>.py[:PRESETS] is required")
  compile_cache.enable()
  return config_flags.get_config_filename(flag), config_flags.get_override_values(flag)
