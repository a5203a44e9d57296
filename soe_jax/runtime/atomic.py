"""Files written atomically: into a temporary name beside the target, then renamed over it, so that a
reader (or a resumed run) sees the old file or the new one, never half of one."""

from __future__ import annotations

import contextlib
import json
import os
import re
import shutil
import sys
from collections.abc import Iterator

from soe_jax.runtime import faults, hosts


@contextlib.contextmanager
def replacing(path: str, suffix: str = "") -> Iterator[str]:
  """Yield a temporary path to write to; on success it replaces `path` (a file or a directory), on an
  error it is removed. `suffix`: the temporary name's ending, for writers that go by it (".mp4"). The
  moment before the rename is the enclosing write site's `faults.during()`. On a host other than the
  writer (`hosts`), the temporary path is written and removed, and `path` is left alone."""
  tmp = f"{path}.tmp-{os.getpid()}{suffix}"
  try:
    yield tmp
    faults.during()
  except BaseException:
    _remove(tmp)
    raise
  if not hosts.writer():
    _remove(tmp)
    return
  if os.path.isdir(path) and not os.path.islink(path):
    shutil.rmtree(path)
  os.replace(tmp, path)


_TEMPORARY = re.compile(r"\.tmp-(\d+)")


def remove_stale(directory: str) -> list[str]:
  """Remove the temporary files and directories under `directory` that a killed writer left (`replacing`'s
  names, whose process is gone) -> their paths. Those of a live process are its writes in progress."""
  removed = []
  if not hosts.writer():  # (another host's process ids mean nothing here)
    return removed
  for parent, dirs, files in os.walk(directory):
    for name in dirs + files:
      if (m := _TEMPORARY.search(name)) and not _alive(int(m.group(1))):
        _remove(os.path.join(parent, name))
        removed.append(os.path.join(parent, name))
    dirs[:] = [d for d in dirs if os.path.join(parent, d) not in removed]
  return removed


def _alive(pid: int) -> bool:
  try:
    os.kill(pid, 0)
  except ProcessLookupError:
    return False
  except PermissionError:  # another user's
    return True
  return True


def _remove(path: str) -> None:
  if os.path.isdir(path) and not os.path.islink(path):
    shutil.rmtree(path, ignore_errors=True)
  elif os.path.exists(path):
    os.remove(path)


def write_json(path: str, obj, indent: int | None = 2) -> None:
  """Write `obj` to `path` as JSON, atomically and durably (on disk before it is renamed into place)."""
  with replacing(path) as tmp, open(tmp, "w") as f:
    json.dump(obj, f, indent=indent)
    f.flush()
    os.fsync(f.fileno())


def write_text(path: str, text: str) -> None:
  """Write `text` to `path`, atomically and durably."""
  with replacing(path) as tmp, open(tmp, "w") as f:
    f.write(text)
    f.flush()
    os.fsync(f.fileno())


def copy(source: str, path: str) -> None:
  """Copy the file `source` to `path`, atomically and durably."""
  with replacing(path) as tmp:
    shutil.copyfile(source, tmp)
    with open(tmp, "rb+") as f:
      os.fsync(f.fileno())


def read_json(path: str):
  with open(path) as f:
    return json.load(f)


def read_record(path: str):
  """A record that marks something done -> its content, or None when it is missing, empty or not
  JSON (a write cut short on a file system that does not order them): "not done"."""
  try:
    with open(path) as f:
      return json.load(f)
  except FileNotFoundError:
    return None
  except ValueError:
    print(f"warning: {path} is empty or not JSON: taken as not done", file=sys.stderr, flush=True)
    return None
