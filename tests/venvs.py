"""Virtual environments of their own for the slow tests that run other projects' code (LeRobot's
writer, lerobot-doctor, openpi-client with numpy < 2): made once under VENVS (outside the repository;
`SOE_JAX_VENVS` moves it) and reused."""

import os
import subprocess

import pytest

VENVS = os.environ.get("SOE_JAX_VENVS", "/work/venvs")


def python(name: str, packages: list[str], probe: str, env: dict | None = None, timeout: int = 3000,
           no_deps: list[str] = ()) -> str:  # fmt: skip
  """The python of the virtual environment `name` with `packages`, then `no_deps` installed without their
  dependencies (a package whose pins contradict the others'), made once (reused while `probe` runs
  there); pytest.skip with pip's last error line where it cannot be made."""
  exe = os.path.join(VENVS, name, "bin", "python")
  if os.path.exists(exe) and subprocess.run([exe, "-c", probe], capture_output=True).returncode == 0:
    return exe
  try:
    subprocess.run(["python3", "-m", "venv", os.path.join(VENVS, name)], check=True, capture_output=True)
    r = subprocess.run([exe, "-m", "pip", "install", "-q", *packages], capture_output=True, text=True,
                       timeout=timeout, env=env)  # fmt: skip
    if not r.returncode and no_deps:
      r = subprocess.run([exe, "-m", "pip", "install", "-q", "--no-deps", *no_deps], capture_output=True,
                         text=True, timeout=timeout, env=env)  # fmt: skip
  except (OSError, subprocess.SubprocessError) as e:
    pytest.skip(f"cannot make the virtual environment {name}: {e}")
  if r.returncode or subprocess.run([exe, "-c", probe], capture_output=True).returncode:
    pytest.skip(
      f"pip cannot install {packages} into {VENVS}/{name}: {r.stderr.strip().splitlines()[-1:] or r.returncode}"
    )
  return exe
