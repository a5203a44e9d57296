"""The launch scripts' work directories: under $RUNS, else under the main checkout's runs/, also when a
script runs from a linked worktree pinned to an older commit (removed after, with whatever is in it)."""

import os
import pathlib
import shutil
import subprocess

from tests.launch.test_science_scripts import ROOT, _lines


def _runs_root(launch: pathlib.Path, **env) -> str:
  command = f"source {launch / 'runs.sh'}; runs_root"
  environ = {k: v for k, v in os.environ.items() if k != "RUNS"} | env
  return subprocess.run(["bash", "-c", command], env=environ, capture_output=True, text=True, check=True).stdout.strip()


def test_the_default_is_the_main_checkouts_runs_even_from_a_linked_worktree(tmp_path):
  git = ["git", "-c", "user.name=t", "-c", "user.email=t@example.com"]
  main, pinned, plain = tmp_path / "main", tmp_path / "pinned", tmp_path / "plain"
  for folder in (main, plain):
    (folder / "launch").mkdir(parents=True)
    shutil.copy(ROOT / "launch" / "runs.sh", folder / "launch")
  subprocess.run([*git, "init", "-q", str(main)], check=True)
  subprocess.run([*git, "-C", str(main), "add", "launch"], check=True)
  subprocess.run([*git, "-C", str(main), "commit", "-qm", "launch"], check=True)
  subprocess.run([*git, "-C", str(main), "worktree", "add", "-q", "--detach", str(pinned)], check=True)
  assert _runs_root(main / "launch") == str(main / "runs")
  assert _runs_root(pinned / "launch") == str(main / "runs")  # not pinned/runs
  assert _runs_root(plain / "launch") == str(plain / "runs")  # outside a git checkout: beside launch/
  assert _runs_root(pinned / "launch", RUNS="/data/runs") == "/data/runs"


def test_the_science_scripts_work_under_runs_by_default(tmp_path, monkeypatch):
  monkeypatch.setenv("RUNS", str(tmp_path / "runs"))
  monkeypatch.setenv("CONFIG", "configs/lift.py:smoke")
  (argv,) = _lines(tmp_path, "protocol.sh", "main-can-1", "1")
  assert f"--workdir={tmp_path}/runs/protocol/can-1" in argv
  lines = _lines(tmp_path, "why_own_successes.sh", "1", "", "a")  # (an empty WORKDIR: the default)
  assert f"--workdir={tmp_path}/runs/why" in lines[0]
