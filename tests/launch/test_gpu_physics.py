"""The GPU scripts under launch/ run commands that exist: every command line `launch/gpu_physics.py` and
`launch/gpu_image.py` would run parses with its command's flags (parsed only: nothing compiles)."""

import importlib
import pathlib
import sys

import pytest

from soe_jax import __main__ as dispatcher
from soe_jax.commands import bench
from soe_jax.runtime import cli

ROOT = pathlib.Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def launch():
  """The scripts as modules (gpu_image imports gpu_physics from its own directory)."""
  sys.path.insert(0, str(ROOT / "launch"))
  try:
    yield importlib.import_module("gpu_physics"), importlib.import_module("gpu_image")
  finally:
    sys.path.remove(str(ROOT / "launch"))


def _command_lines(launch) -> list[list[str]]:
  physics, image = launch
  cases = physics.cases() + [c for presets in ("image", "smoke,image") for c in image.cases(presets)]
  return [physics.command(args) for _, args in cases]


def _parse(argv: list[str], monkeypatch) -> list[str]:
  """`python -m soe_jax COMMAND [SUB] flags` parsed with a fresh copy of that command's flags -> the
  positional arguments left (the command's name first)."""
  assert argv[:3] == [sys.executable, "-m", "soe_jax"] and argv[3] in dispatcher.COMMANDS, argv
  # As `python -m soe_jax` would see it (ml_collections reads `--config.a.b=v` from sys.argv).
  monkeypatch.setattr(sys, "argv", [str(ROOT / "soe_jax" / "__main__.py"), *argv[3:]])
  name = argv[3]
  if name == "bench":
    sub = argv[4]
    assert sub in bench.BENCHMARKS, argv
    required = ("config",) if bench.BENCHMARKS[sub].config else ()
    return cli.parse(bench.flags(sub), [f"python -m soe_jax bench {sub}", *argv[5:]], required)
  command = importlib.import_module(f"soe_jax.commands.{name}")
  command.FLAGS.unparse_flags()
  return cli.parse(command.FLAGS, [f"python -m soe_jax {name}", *argv[4:]])


def test_every_command_line_of_the_gpu_scripts_parses(launch, monkeypatch, capsys):
  monkeypatch.chdir(ROOT)  # (the config files are named from the repository root, as the scripts run)
  lines = _command_lines(launch)
  assert {argv[4] for argv in lines} == {"env", "mjx", "rollout", "encoder", "fit", "sample"}
  for argv in lines:
    try:
      rest = _parse(argv, monkeypatch)
    except SystemExit:
      pytest.fail(f"{' '.join(argv[3:])}: {capsys.readouterr().err.strip()}")
    assert len(rest) == 1, argv  # no stray positional arguments


def test_a_line_with_another_benchmarks_flag_does_not_parse(monkeypatch, capsys):
  """A command line with a flag of another benchmark does not parse."""
  with pytest.raises(SystemExit) as exit:
    _parse([sys.executable, "-m", "soe_jax", "bench", "env", "--bypass=on"], monkeypatch)
  assert exit.value.code == 2 and "bypass" in capsys.readouterr().err
