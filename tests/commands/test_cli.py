"""What every command shares: `--help` exits 0 without import noise, a mistake is one `error:` line
with exit status 2, and listing the commands imports neither JAX nor MuJoCo."""

import importlib
import os
import re
import subprocess
import sys

import pytest

from soe_jax import __main__ as entry
from soe_jax.commands import export as export_command
from soe_jax.commands import run as run_command
from soe_jax.data import export
from soe_jax.runtime import cli

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

# Every command's --help in one process (a study's own name among them), with MuJoCo Warp unimportable
# (as without the `gpu` extra, where MJX prints "Failed to import warp" at import): what each printed,
# and its exit status.
_HELP_ALL = """
import contextlib, io, json, sys
from soe_jax import __main__ as entry
out = {}
for name in sys.argv[1:]:
  buf = io.StringIO()
  with contextlib.redirect_stdout(buf):
    try:
      entry.main(["soe_jax", name, "--help"])
      code = None
    except SystemExit as e:
      code = e.code
  out[name] = [code, buf.getvalue()]
print(json.dumps(out))
"""


def _run(args, tmp_path=None):
  env = dict(os.environ)
  if tmp_path is not None:  # a `warp` package that fails to import, first on the path
    (tmp_path / "warp").mkdir(exist_ok=True)
    (tmp_path / "warp" / "__init__.py").write_text("raise ImportError('warp is not installed here')\n")
    env["PYTHONPATH"] = os.pathsep.join([str(tmp_path), ROOT])
  return subprocess.run([sys.executable, *args], capture_output=True, text=True, cwd=ROOT, env=env, timeout=300)


def test_listing_the_commands_imports_neither_jax_nor_mujoco():
  script = (
    "import sys\nfrom soe_jax import __main__ as m\ntry:\n  m.main(['soe_jax', '--help'])\nexcept SystemExit as e:\n"
    "  assert e.code == 0\nassert not {'jax', 'mujoco'} & set(sys.modules), sorted({'jax', 'mujoco'} & set(sys.modules))"
  )
  done = _run(["-c", script])
  assert done.returncode == 0, done.stderr
  assert all(f"  {name} " in done.stdout for name in entry.COMMANDS)


def test_every_commands_help_exits_0_without_import_noise(tmp_path):
  import json

  done = _run(["-c", _HELP_ALL, *entry.COMMANDS, *entry.STUDY_COMMANDS], tmp_path)
  assert done.returncode == 0, done.stderr[-3000:]
  assert "Failed to import" not in done.stdout + done.stderr
  for name, (code, text) in json.loads(done.stdout.splitlines()[-1]).items():
    assert code == 0, (name, code)
    usage = f"python -m soe_jax study {name}" if name in entry.STUDY_COMMANDS else f"python -m soe_jax {name}"
    assert usage in text, (name, text[:300])


def test_mistakes_are_one_error_line_with_exit_2(capsys):
  """In one process too: a command run again starts from its defaults, without the last overrides."""
  cases = {
    ("run",): "error: --config=configs/<task>.py[:PRESETS] is required",
    ("run", "--config=configs/lift.py:smoke,fast"): "error: unknown preset 'fast'; known presets: smoke",
    ("run", "--config=configs/lift.py:smoke", "--config.fit.num_steps=ten"): "base 10: 'ten'",
    ("run", "--config=configs/lift.py:smoke", "--config.fit.num_step=3"): "(did you mean fit.num_steps?)",
    ("nonsense",): "error: unknown command 'nonsense'; known commands: run, compare",
  }
  for args, expected in [*cases.items(), *cases.items()]:  # (twice: the flags of a run do not linger)
    with pytest.raises(SystemExit) as stopped:
      entry.main(["soe_jax", *args])
    lines = capsys.readouterr().err.strip().splitlines()
    assert stopped.value.code == 2 and len(lines) == 1 and lines[0].startswith("error: "), (args, lines)
    assert expected in lines[0], (args, lines[0])
    assert "Error:" not in lines[0], lines[0]  # no exception class names


def test_run_help_says_round_0_is_written_outside_the_workdir():
  text = " ".join(cli.help_text(run_command.__doc__, run_command.FLAGS).split())
  assert "Round 0 (demonstrations, fit, evaluation) is written outside the workdir" in text, text
  assert "DIR/../round0/<task>-<hash>/" in text, text


def _readme_commands() -> dict[str, str]:
  """{command: its row} of the README's command table."""
  rows = [line for line in open(os.path.join(ROOT, "README.md")) if line.startswith("| `")]
  return {name: row for row in rows for name in re.findall(r"`(\w+)`", row.split("|")[1])}


def test_the_readmes_command_table_names_every_command():
  assert set(entry.COMMANDS) - set(_readme_commands()) == set()


def test_export_help_the_listing_and_the_readme_name_the_same_formats():
  """Each of export's formats by the name the documents give it, in `export --help`'s first line, the
  command listing and the README's command table."""
  names = {"robomimic": "robomimic HDF5", "zarr": "zarr", "rlds": "RLDS", "lerobot": "LeRobotDataset"}
  assert set(names) == set(export.FORMATS)
  places = {
    "export --help": cli.help_text(export_command.__doc__, export_command.FLAGS).splitlines()[0],
    "python -m soe_jax --help": entry.COMMANDS["export"],
    "README.md": _readme_commands()["export"],
  }
  missing = [f"{place}: {name}" for place, text in places.items() for name in names.values() if name not in text]
  assert missing == []


@pytest.mark.parametrize("name", ["run", "experts", "export", "inspect"])
def test_the_files_a_commands_help_names_exist(name):
  """A path in a command's `--help` is from the repository's root (`soe_jax/experiment/presets.py`)."""
  module = importlib.import_module(f"soe_jax.commands.{name}")
  paths = re.findall(r"[\w/]+/\w+\.py\b", cli.help_text(module.__doc__, module.FLAGS))
  assert [p for p in paths if not os.path.exists(os.path.join(ROOT, p))] == []
