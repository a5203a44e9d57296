"""The base install (`pip install -e .`) has no pyarrow, which only the `robot` extra installs: `export`
and `inspect` still answer `--help` and handle robomimic's HDF5, and a LeRobotDataset is one `error:`
line naming the extra, with exit status 2 (as is zarr without the `zarr` extra)."""

import json
import os
import subprocess
import sys

import numpy as np

from soe_jax.data import hdf5

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
LEROBOT_FIXTURE = os.path.join(ROOT, "tests", "data", "fixtures", "lerobot_v3_tiny")
EXTRA = 'pip install -e ".[robot]"'

# Each command line in one process where pyarrow cannot be imported: its exit status, stdout and stderr;
# then `export.write` in the lerobot and zarr formats: their errors and whether anything was written.
_WITHOUT_PYARROW = """
import contextlib, io, json, os, sys
from soe_jax import __main__ as entry
out = []
for line in json.loads(sys.argv[1]):
  stdout, stderr = io.StringIO(), io.StringIO()
  with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr):
    try:
      entry.main(["soe_jax", *line])
      code = 0
    except SystemExit as e:
      code = e.code
  out.append([code, stdout.getvalue(), stderr.getvalue()])
from soe_jax.data import export
from soe_jax.data.episodes import EpisodeSet
from soe_jax.runtime.errors import UserError
errors = {}
for fmt in ("lerobot", "zarr"):
  try:
    export.write(sys.argv[2], fmt, [EpisodeSet([], 0)], {"env_kwargs": {}})
  except UserError as e:
    errors[fmt] = str(e)
print(json.dumps([out, errors, os.path.exists(sys.argv[2])]))
"""


def test_export_and_inspect_without_pyarrow(tmp_path):
  path = str(tmp_path / "demos.hdf5")
  episode = dict(actions=np.zeros((5, 10), np.float32), obs={"robot0_eef_pos": np.zeros((5, 3), np.float32)})
  hdf5.write_episodes(path, [episode, episode], {"env_name": "lift"})
  for name in ("pyarrow", "zarr"):  # packages that fail to import, first on the path (as when they are absent)
    (tmp_path / name).mkdir()
    (tmp_path / name / "__init__.py").write_text(f"raise ModuleNotFoundError('no {name} installed', name={name!r})\n")
  lines = [["export", "--help"], ["inspect", "--help"], ["inspect", path], ["inspect", LEROBOT_FIXTURE]]
  env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(tmp_path), ROOT]))
  out = str(tmp_path / "data.lerobot")
  args = [sys.executable, "-c", _WITHOUT_PYARROW, json.dumps(lines), out]
  done = subprocess.run(args, capture_output=True, text=True, cwd=ROOT, env=env, timeout=300)
  assert done.returncode == 0, done.stderr[-3000:]
  (export_help, inspect_help, hdf5_file, lerobot_dir), errors, written = json.loads(done.stdout.splitlines()[-1])
  assert export_help[0] == 0 and "python -m soe_jax export" in export_help[1], export_help
  assert inspect_help[0] == 0 and "python -m soe_jax inspect" in inspect_help[1], inspect_help
  assert hdf5_file[0] == 0 and f"{path}: 2 episodes, 10 steps" in hdf5_file[1], hdf5_file
  code, _, err = lerobot_dir
  assert code == 2 and err.count("\n") == 1 and err.startswith("error: ") and EXTRA in err, lerobot_dir
  assert EXTRA in errors["lerobot"] and "pyarrow" in errors["lerobot"], errors
  assert 'pip install -e ".[zarr]"' in errors["zarr"] and not written, (errors, written)
