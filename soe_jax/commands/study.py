"""Measurement studies (`soe_jax/analysis/studies/`), each with its settings as flags.

  python -m soe_jax study                      # the studies, one line each
  python -m soe_jax study NAME --help          # what NAME measures, and its flags
  python -m soe_jax study NAME [RUN_DIR ...] [--field=value ...] [--out=FILE]

A study's flags are its settings (the fields of its dataclass), with `--config` for a study of a
config and `--out` for one that writes a record. It prints what it found; `--out` also writes its
record (its kind, the command, the commit and the machine, what it measured) for `results/`, where
`python -m soe_jax results` tables it. The studies that launch scripts and committed records name by
their own name are commands of that name too (`python -m soe_jax converge` is `python -m soe_jax study
converge`; `python -m soe_jax --help` lists them).
"""

from __future__ import annotations

import dataclasses
import sys
import types
import typing

from soe_jax.analysis.studies import registry
from soe_jax.analysis.studies.study import Study
from soe_jax.runtime import cli
from soe_jax.runtime.errors import UserError

USAGE = "python -m soe_jax study NAME [RUN_DIR ...] [--field=value ...] [--out=FILE]"
HELP = ("-h", "--help", "-help", "--helpshort", "--helpfull", "help")


def _flag_type(hint) -> tuple[type, type | None]:
  """A setting's type -> (its flag's type, the type of a list's elements): `str | None` is a string,
  `tuple[float, ...]` a list of floats."""
  if isinstance(hint, types.UnionType) or typing.get_origin(hint) is typing.Union:
    hint = next(a for a in typing.get_args(hint) if a is not type(None))
  if typing.get_origin(hint) is tuple:
    return tuple, typing.get_args(hint)[0]
  return hint, None


def define(study: type[Study]) -> cli.Flags:
  """A fresh set of `study`'s flags: `--config` if it takes one, a flag per setting, `--out` if it
  writes a record."""
  f = cli.Flags()
  if study.config:
    f.config_flag()
  hints = typing.get_type_hints(study)
  for field in dataclasses.fields(study):
    name, meta = field.name, field.metadata
    default = None if field.default is dataclasses.MISSING else field.default
    kind, element = _flag_type(hints[name])
    bound = {} if meta["lower_bound"] is None else dict(lower_bound=meta["lower_bound"])
    if meta["values"]:
      f.enum(name, default, list(meta["values"]), meta["help"])
    elif kind is bool:
      f.boolean(name, default, meta["help"])
    elif kind is int:
      f.integer(name, default, meta["help"], **bound)
    elif kind is float:
      f.float(name, default, meta["help"], **bound)
    elif kind is tuple:
      shown = None if default is None else [format(v, "g") if element is float else str(v) for v in default]
      f.list(name, shown, meta["help"])
    else:
      f.string(name, default, meta["help"])
  if study.kind is not None:
    writes = "Where the record goes." if study.record_required else "Also write the record (for results/) here."
    f.string("out", None, writes)
  return f


FLAGS = {name: define(registry.study(name)) for name in registry.study_names()}


def flags(name: str) -> cli.Flags:
  """Study `name`'s flags (defined once)."""
  if name not in FLAGS:
    FLAGS[name] = define(registry.study(name))
  return FLAGS[name]


def settings(study: type[Study], f: cli.Flags) -> Study:
  """`study` with the settings its parsed flags `f` give."""
  hints = typing.get_type_hints(study)
  values = {}
  for field in dataclasses.fields(study):
    value = f[field.name].value
    kind, element = _flag_type(hints[field.name])
    if kind is tuple and value is not None:
      try:
        value = tuple(element(v) for v in value)
      except ValueError:
        given = ",".join(value)
        raise cli.UsageError(f"--{field.name} takes {element.__name__}s separated by commas; got {given}") from None
    values[field.name] = value
  return study(**values)


def help_text() -> str:
  """The module's docstring, then each study's name and what it measures."""
  studies = registry.studies()
  width = max(map(len, studies))
  lines = [f"  {name:<{width}}  {study.what()}" for name, study in studies.items()]
  return __doc__.strip() + "\n\nstudies:\n" + "\n".join(lines) + "\n"


def _run(study: type[Study], f: cli.Flags, rest: list[str], command: str) -> None:
  paths = cli.positional(rest, study.takes, f"{command} {study.usage} [flags]".replace("  ", " "))
  made = settings(study, f)
  record = made.run(paths, f.config if study.config else None)
  print(made.report(record), end="")
  if study.kind is not None and f.out:
    made.write(record, f.out)
    print(f"-> {f.out}")


def run(name: str, argv: list[str]) -> None:
  """Study `name` with the command line `argv`, its command's name first (`python -m soe_jax study
  NAME`, or the study's own command name)."""
  study, f = registry.study(name), flags(name)
  required = tuple(field.name for field in dataclasses.fields(study) if field.default is dataclasses.MISSING)
  required = (("config",) if study.config else ()) + required + (("out",) if study.record_required else ())
  cli.run(lambda rest: _run(study, f, rest, argv[0]), f, study.doc(), argv, required=required,
          interrupted=study.interrupted, compiles=study.compiles)  # fmt: skip


def main(argv: list[str] | None = None) -> None:
  argv = list(sys.argv if argv is None else argv)
  name = argv[1] if len(argv) > 1 else None
  if name is None or name in HELP:
    print(help_text(), end="")
    sys.exit(0)
  try:
    registry.STUDIES.check(name)
  except UserError as e:
    cli.fail(f"{e}; usage: {USAGE}")
  run(name, [f"{argv[0]} {name}", *argv[2:]])
