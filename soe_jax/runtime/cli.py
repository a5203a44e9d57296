"""What every command shares (`commands/`): its own flags (a `Flags` per command, so that commands'
flags never collide), `--help` that exits 0, a mistake in the command line or a `UserError` as one
`error:` line on stderr with exit status 2 (anything else keeps its traceback), absl's INFO lines
silenced, SIGTERM handled as Ctrl-C, and Ctrl-C as a line on stderr with exit status 130."""

from __future__ import annotations

import errno
import re
import sys
from collections.abc import Callable
from typing import NoReturn

from absl import flags, logging
from ml_collections import config_flags

from soe_jax.runtime import compile_cache, configfile, hosts, interrupt, sharding
from soe_jax.runtime.errors import UserError

CONFIG_HELP = "configs/<task>.py[:PRESETS]"


class UsageError(UserError):
  """A command line the command cannot run: a missing flag, an unexpected argument."""


class Flags(flags.FlagValues):
  """One command's flags: absl's `FlagValues` with the helpers the commands use."""

  def config_flag(self, help: str = CONFIG_HELP) -> None:
    """`--config=configs/<task>.py[:PRESETS]` with `--config.a.b=v` overrides (typos fail)."""
    config_flags.DEFINE_config_file("config", None, help, flag_values=self, lock_config=True)

  def string(self, name, default, help, **kw):
    flags.DEFINE_string(name, default, help, flag_values=self, **kw)

  def integer(self, name, default, help, **kw):
    flags.DEFINE_integer(name, default, help, flag_values=self, **kw)

  def float(self, name, default, help, **kw):
    flags.DEFINE_float(name, default, help, flag_values=self, **kw)

  def boolean(self, name, default, help, **kw):
    flags.DEFINE_bool(name, default, help, flag_values=self, **kw)

  def list(self, name, default, help, **kw):
    flags.DEFINE_list(name, default, help, flag_values=self, **kw)

  def multi_string(self, name, default, help, **kw):
    """A flag given any number of times (`--method a --method b`) -> the list of its values."""
    flags.DEFINE_multi_string(name, default, help, flag_values=self, **kw)

  def enum(self, name, default, values, help, **kw):
    flags.DEFINE_enum(name, default, values, help, flag_values=self, **kw)

  def config_file(self) -> tuple[str, dict]:
    """The `--config` flag's file spec and its `--config.a.b=v` overrides ({"a.b": v})."""
    return config_flags.get_config_filename(self["config"]), config_flags.get_override_values(self["config"])


def fail(message: str) -> NoReturn:
  print(f"error: {message}", file=sys.stderr, flush=True)
  sys.exit(2)


def message(e: BaseException) -> str:
  """An exception's last non-empty line, without its class name; a `KeyError`'s quotes (which `str`
  adds around the whole message) removed, any quotes inside it kept."""
  text = str(e.args[0]) if isinstance(e, KeyError) and e.args else str(e)
  lines = [line for line in text.strip().splitlines() if line.strip()]
  # A wrapped exception's class name ("ValueError: unknown preset ...") is not the user's business.
  return re.sub(r"^[A-Za-z_.]*(Error|Exception): ", "", lines[-1].strip()) if lines else type(e).__name__


def positional(argv: list[str], count: str, usage: str) -> list[str]:
  """The positional arguments after the command's name, checked: `count` is "0", "1", "1+" or "0+";
  otherwise a `UsageError` with `usage`."""
  args = argv[1:]
  ok = {"0": len(args) == 0, "1": len(args) == 1, "1+": len(args) >= 1, "0+": True}[count]
  if not ok:
    raise UsageError(f"{'unexpected arguments: ' + ' '.join(args) if args else 'missing arguments'}; usage: {usage}")
  return args


def parse(flag_values: Flags, argv: list[str], required: tuple[str, ...] = ()) -> list[str]:
  """Parse `argv` (the command's name first) -> the positional arguments (the name first). A mistake
  is one `error:` line and exit status 2: an unknown flag, a bad value, a misspelled `--config.a.b`
  (with the closest field), a bad preset, a missing required flag."""
  flag_values.unparse_flags()  # a command run twice in one process starts from its defaults
  for name in [n for n in flag_values if n.startswith("config.")]:  # and without the last run's overrides
    delattr(flag_values, name)
  given = next((a.split("=", 1)[1] for a in argv if a.startswith("--config=")), None)
  if given is not None:
    path, colon, presets = given.partition(":")
    resolved = configfile.resolve(path)  # the repository's configs/ from any directory
    try:
      configfile.check(resolved)  # a file that cannot be a config: one line, before it runs
    except UserError as e:
      fail(str(e))
    if resolved != path:
      argv = [f"--config={resolved}{colon}{presets}" if a == f"--config={given}" else a for a in argv]
  saved, sys.argv = sys.argv, list(argv)  # (ml_collections reads `--config.a.b=v` from sys.argv)
  try:
    rest = flag_values(argv)
  except (AttributeError, KeyError, ValueError, TypeError, flags.Error) as e:
    spec = next((a.split("=", 1)[1] for a in argv if a.startswith("--config=")), None)
    if spec is not None:
      try:
        unknown = configfile.unknown_overrides(spec, argv)
      except Exception:  # the config file itself is what fails: report the original error
        unknown = []
      if unknown:
        fail(f"unknown config field {', '.join(unknown)}")
    fail(message(e))
  finally:
    sys.argv = saved
  for name in required:
    if flag_values[name].value is None:
      hint = f"={CONFIG_HELP}" if name == "config" else ""
      fail(f"--{name}{hint} is required (--help lists the flags)")
  return rest


def help_text(doc: str, flag_values: Flags) -> str:
  """The command's docstring, then its flags, one line each."""
  lines = []
  for name in flag_values:
    f = flag_values[name]
    if f.name != name:  # (a short name)
      continue
    default = "" if f.default is None else f" (default: {f.default_as_str or repr(f.default)})"
    lines.append(f"  --{name}: {f.help}{default}")
  return doc.strip() + ("\n\nflags:\n" + "\n".join(lines) if lines else "") + "\n"


# What a command that saves each finished phase prints on Ctrl-C (`run`'s `interrupted`).
PHASES_SAVED = "interrupted: the finished phases are saved; run the same command to resume"


def run(
  main: Callable[[list[str]], None],
  flag_values: Flags,
  doc: str,
  argv: list[str] | None = None,
  required: tuple[str, ...] = (),
  interrupted: str = "interrupted",
  compiles: bool = False,
) -> None:
  """Parse `argv` (default `sys.argv`) with `flag_values` and call `main(positional arguments)` with
    the above; `doc` is what `--help` prints above the flags; `interrupted` is what Ctrl-C prints (a
    command that saves its work says where, and how to go on); `compiles`: the command compiles with JAX,
  so once its flags are parsed a multi-host run starts (when cluster variables describe one) and the
  persistent compilation cache is turned on."""
  argv = list(sys.argv if argv is None else argv)
  if any(a in ("-h", "--help", "-help", "--helpshort", "--helpfull") for a in argv[1:]):
    print(help_text(doc, flag_values), end="")
    sys.exit(0)
  rest = parse(flag_values, argv, required)
  if compiles:
    sharding.maybe_initialize_distributed()
    compile_cache.enable()
  logging.set_verbosity(logging.WARNING)
  interrupt.terminate_as_interrupt()
  try:
    main(rest)
    hosts.barrier("done")  # leave together: JAX's shutdown barrier waits only minutes for a peer
  except UserError as e:
    fail(str(e))
  except OSError as e:
    if e.errno not in (errno.ENOSPC, errno.EDQUOT):
      raise
    where = f"{e.filename}: " if e.filename else ""
    fail(f"{where}no space left on the device; the file being written was removed, the ones before it are whole: "
         "free some space and run the same command again to go on")  # fmt: skip
  except KeyboardInterrupt:
    print(f"\n{interrupted}", file=sys.stderr, flush=True)
    sys.exit(130)
