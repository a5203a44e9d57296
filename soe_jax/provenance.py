"""Where a measurement comes from, for the records committed under `results/`: the command, the commit
(with `+changes` when the tree differs from it) and the machine."""

from __future__ import annotations

import os
import platform
import shlex
import subprocess
import sys


def _git(*args: str) -> str:
  try:
    return subprocess.run(["git", *args], capture_output=True, text=True, check=True).stdout.strip()
  except (OSError, subprocess.CalledProcessError):
    return ""


def commit() -> str:
  head = _git("rev-parse", "--short", "HEAD") or "unknown"
  return head + ("+changes" if _git("status", "--porcelain", "--untracked-files=no") else "")


def machine() -> str:
  import jax
  import mujoco

  cpu = platform.processor() or platform.machine()
  try:
    with open("/proc/cpuinfo") as f:
      cpu = next(line.split(":", 1)[1].strip() for line in f if line.startswith("model name"))
  except (OSError, StopIteration):
    pass
  try:
    memory = f", {os.sysconf('SC_PAGE_SIZE') * os.sysconf('SC_PHYS_PAGES') / 2**30:.0f} GiB"
  except (ValueError, OSError, AttributeError):
    memory = ""
  devices = ", ".join(sorted({d.device_kind for d in jax.devices()}))
  return (
    f"{os.cpu_count()} cores of {cpu}{memory}; JAX {jax.__version__} on {jax.default_backend()} ({devices}), "
    f"MuJoCo {mujoco.__version__}"
  )


def header(argv: list[str] | None = None) -> dict:
  """{command, commit, machine} of the running command."""
  argv = sys.argv if argv is None else argv
  module = argv[0].removesuffix(".py").split("soe_jax/")[-1].replace("/", ".").removesuffix(".__main__")
  command = "python -m soe_jax." + module if "soe_jax" in argv[0] else "python " + argv[0]
  return dict(command=" ".join([command] + [shlex.quote(a) for a in argv[1:]]), commit=commit(), machine=machine())
