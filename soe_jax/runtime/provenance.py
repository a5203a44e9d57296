"""Where a measurement comes from, for the records committed under `results/`: the command, the commit
(with `+changes` when the tree differs from it) and the machine."""

from __future__ import annotations

import importlib.metadata
import os
import platform
import shlex
import subprocess
import sys

import jax


def _git(*args: str) -> str:
  try:
    return subprocess.run(["git", *args], capture_output=True, text=True, check=True).stdout.strip()
  except (OSError, subprocess.CalledProcessError):
    return ""


def commit() -> str:
  """The commit checked out, with `+changes` when a tracked file outside `results/` differs from it (a
  campaign rewriting its results' tables while a measurement runs leaves the code as committed)."""
  head = _git("rev-parse", "--short", "HEAD") or "unknown"
  changed = _git("status", "--porcelain", "--untracked-files=no", "--", ".", ":(exclude)results")
  return head + ("+changes" if changed else "")


def machine() -> str:
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
    f"MuJoCo {importlib.metadata.version('mujoco')}"  # (the version without importing MuJoCo)
  )


def command(argv: list[str]) -> str:
  """The command line `argv` as one would type it: `python -m soe_jax bench env --out=...` from the
  dispatcher's `sys.argv` (its `soe_jax/__main__.py` first) or from a command's own argv (its name,
  "python -m soe_jax bench env", first), `python -m soe_jax.<module> ...` from a module's."""
  if argv[0].startswith("python -m "):  # a command's name, as the dispatcher passes it
    name = argv[0]
  elif "soe_jax" in argv[0]:
    module = argv[0].removesuffix(".py").split("soe_jax/")[-1].replace("/", ".").removesuffix("__main__").rstrip(".")
    name = "python -m soe_jax" + (f".{module}" if module else "")
  else:
    name = "python " + argv[0]
  return " ".join([name] + [shlex.quote(a) for a in argv[1:]])


def header(argv: list[str] | None = None) -> dict:
  """{command, commit, machine} of the running command (`argv`: default `sys.argv`; see `command`)."""
  argv = sys.argv if argv is None else argv
  return dict(command=command(argv), commit=commit(), machine=machine())
