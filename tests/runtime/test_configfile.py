"""`--config=configs/<task>.py` from any directory: a relative path the current directory lacks is the
repository's (the package is installed editable from it); one that neither has says where it looked."""

import os

import pytest

from soe_jax import __main__ as entry
from soe_jax.runtime import cli, configfile

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def test_the_repositorys_configs_load_from_another_directory(tmp_path, monkeypatch):
  monkeypatch.chdir(tmp_path)
  assert configfile.resolve("configs/lift.py") == os.path.join(ROOT, "configs", "lift.py")
  assert configfile.load("configs/lift.py:smoke").env.task == "lift"
  flags = cli.Flags()
  flags.config_flag()
  cli.parse(flags, ["prog", "--config=configs/lift.py:smoke", "--config.seed=3"])
  assert flags.config.env.task == "lift" and flags.config.seed == 3
  same = configfile.load(os.path.join(ROOT, "configs/lift.py:smoke"), overrides={"seed": 3})
  assert flags.config.to_json_best_effort() == same.to_json_best_effort()


def test_a_file_in_the_current_directory_comes_first(tmp_path, monkeypatch):
  monkeypatch.chdir(tmp_path)
  (tmp_path / "configs").mkdir()
  (tmp_path / "configs" / "lift.py").write_text("def get_config(arg=None):\n  return None\n")
  assert configfile.resolve("configs/lift.py") == "configs/lift.py"


def test_a_missing_config_says_the_path_is_relative_to_the_current_directory(tmp_path, monkeypatch, capsys):
  monkeypatch.chdir(tmp_path)
  with pytest.raises(SystemExit) as stopped:
    entry.main(["soe_jax", "run", "--config=configs/lifts.py:smoke"])
  lines = capsys.readouterr().err.strip().splitlines()
  assert stopped.value.code == 2 and len(lines) == 1, lines
  assert lines[0].startswith("error: no config file at 'configs/lifts.py'"), lines
  assert f"relative path is from the current directory, {tmp_path}" in lines[0] and ROOT in lines[0], lines
