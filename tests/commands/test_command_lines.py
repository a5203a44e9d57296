"""Every `python -m soe_jax ...` line the documents, notebooks, launch scripts and docs show names a
command that exists, flags it defines and presets and config fields that exist (checked against the
commands' definitions, nothing run)."""

import importlib
import json
import os
import re

import pytest

from soe_jax import __main__ as entry
from soe_jax.experiment import presets
from soe_jax.runtime import configfile

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
PLACES = ("README.md", "RESULTS.md", "BENCHMARKS.md", "DESIGN.md", "notebooks", "launch", "docs")
COMMAND = re.compile(r"python -m soe_jax(\.\w+(?:\.\w+)*)?\b")
# A word standing for what the reader chooses: <task>, $seed, {a,b}, ..., TASK.
PLACEHOLDER = re.compile(r"[<>$*{}|]|\.\.\.|\b[A-Z][A-Z_]+\b")
# Modules run by path that are not commands: the run command's older name.
ALIASES = {".main": "run"}


def _texts():
  """(place, text) of every document and script, notebooks by their cells' sources."""
  for place in PLACES:
    path = os.path.join(ROOT, place)
    files = [path] if os.path.isfile(path) else sorted(os.path.join(d, f) for d, _, fs in os.walk(path) for f in fs)
    for f in files:
      if f.endswith(".ipynb"):
        cells = json.load(open(f))["cells"]
        yield os.path.relpath(f, ROOT), "\n".join("".join(c["source"]) for c in cells)
      elif f.endswith((".md", ".py", ".sh")):
        yield os.path.relpath(f, ROOT), open(f).read()


def command_lines():
  """(where, the command's words after `python -m soe_jax`), continuation lines joined; a command
  inside backticks ends at the closing one, else at the end of its line or a shell separator."""
  for place, text in _texts():
    text = re.sub(r"\\\n\s*", " ", text)
    for n, line in enumerate(text.splitlines(), 1):
      for m in COMMAND.finditer(line):
        rest = line[m.end() :]
        if line[: m.start()].count("`") % 2:
          rest = rest.split("`", 1)[0]
        rest = re.split(r"\s(?:&&|\|\||;|\||#)\s|[\"')]\s*$", rest)[0]
        words = [w.strip("[](),.;:'\"") for w in rest.split()]
        words = [w for w in words if w]
        if m.group(1):  # `python -m soe_jax.<module>`: only an alias is a command
          words = [ALIASES.get(m.group(1), f"soe_jax{m.group(1)}")] + words
        yield f"{place}:{n}", words


def _check(words: list[str]) -> list[str]:
  """What is wrong with one command line: an unknown command or flag, preset or config field."""
  if not words or PLACEHOLDER.search(words[0]) or words[0].lower() == "command" or words[0] == "--help":
    return []
  name, *args = words
  if name in entry.STUDY_COMMANDS:  # a study's own name: `study NAME`
    name, args = "study", [name, *args]
  if name not in entry.COMMANDS:
    return [f"unknown command {name!r}"]
  module = importlib.import_module(f"soe_jax.commands.{name}")
  flags = module.FLAGS
  if isinstance(flags, dict):  # a command of sub-commands (bench, study)
    if not args or PLACEHOLDER.search(args[0]):
      return []
    sub = args[0]
    if sub not in flags:
      return [f"{name}: unknown sub-command {sub!r}"]
    flags, args = flags[sub], args[1:]
  out, spec = [], None
  for arg in args:
    if not arg.startswith("--"):
      continue
    flag, _, value = arg[2:].partition("=")
    if flag == "config" and value and not PLACEHOLDER.search(value):
      spec = value.replace("[", "").replace("]", "")  # (an optional part: configs/square.py[:cpu])
  if spec is None and name == "refit":  # (its --config. overrides are the robot run's saved re-fit fields)
    spec = "configs/robot.py"
  config = _config(spec, out)
  for arg in args:
    if not arg.startswith("--") or arg == "--help":
      continue
    flag, _, value = arg[2:].partition("=")
    if flag.startswith("config."):
      field = flag[len("config.") :]
      if config is not None and field not in configfile.keys(config) and not PLACEHOLDER.search(field):
        out.append(f"unknown config field {field!r}")
    elif flag not in flags and not (flag.startswith("no") and flag[2:] in flags):
      out.append(f"{name}: unknown flag --{flag}")
  return out


def _config(spec: str | None, problems: list[str]):
  """The config `--config=FILE[:PRESETS]` gives (Lift's paper-scale one without a concrete file); an
  unknown preset or a missing file is a problem."""
  if spec is None:
    return presets.apply_presets(presets.base_config("lift", 10), "")
  path, _, arg = spec.partition(":")
  if not os.path.exists(os.path.join(ROOT, path)):
    problems.append(f"no config file {path!r}")
    return None
  try:
    return configfile.load(os.path.join(ROOT, spec))
  except ValueError as e:
    problems.append(f"{spec}: {e}")
    return None


def test_the_documents_show_command_lines():
  places = {where.split(":")[0] for where, _ in command_lines()}
  assert {"README.md", "RESULTS.md", "BENCHMARKS.md"} <= places


@pytest.mark.parametrize(
  "words, problem",
  [
    (["run", "--config=configs/lift.py:smoke,soe"], None),
    (["campaign", "--config=configs/lift.py:cpu", "--config.seed=1", "--methods=dp"], None),
    (["bench", "env", "--task=lift", "--num_envs=4"], None),
    (["runs", "--config=configs/lift.py"], "unknown command"),
    (["run", "--config=configs/lift.py:smoke,fast"], "unknown preset 'fast'"),
    (["run", "--config=configs/lift.py", "--config.fit.num_step=3"], "unknown config field"),
    (["compare", "--config=configs/lift.py", "--tries=5"], "unknown flag --tries"),
    (["bench", "fit", "--task=lift"], "unknown flag --task"),
    (["study", "converge", "--config=configs/lift.py:cpu", "--extra=1"], None),
    (["converge", "--config=configs/lift.py:cpu", "--config.fit.num_step=3"], "unknown config field"),
    (["fidelity", "RUN", "--samples=4", "--windows=3"], "unknown flag --windows"),
    (["study", "nonsense"], "unknown sub-command 'nonsense'"),
  ],
)
def test_the_checker_finds_what_it_should(words, problem):
  found = _check(words)
  assert (problem is None and not found) or (problem is not None and any(problem in p for p in found)), found


def test_every_command_line_names_known_commands_and_flags():
  """Every command line names known commands, flags, presets and config fields."""
  problems = [f"{where}: {p}  ({' '.join(words)})" for where, words in command_lines() for p in _check(words)]
  assert not problems, "\n".join(problems)
