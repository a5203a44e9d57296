"""launch/gpu_campaign.py's subprocesses: for one seed, the command lines it starts are
`python -m soe_jax campaign` lines that the command's own flags parse (nothing run, nothing compiled)."""

import importlib
import pathlib
import subprocess
import sys

from soe_jax import __main__ as dispatcher
from soe_jax.analysis import campaign as campaign_lib
from soe_jax.commands import campaign
from soe_jax.runtime import cli

ROOT = pathlib.Path(__file__).resolve().parents[2]


def _parsed(monkeypatch, argv: list[str]):
  """The campaign command's flags as a fresh process parses `argv` (`python -m soe_jax campaign ...`):
  the module reloaded (its `--config.a.b` overrides are flags it defines while parsing, once), and
  `sys.argv` as the dispatcher sees it (`config_flags` reads the overrides from there)."""
  fresh = importlib.reload(campaign)
  monkeypatch.setattr(sys, "argv", [str(ROOT / "soe_jax" / "__main__.py"), *argv[3:]])
  name = "python -m soe_jax campaign"  # what the dispatcher passes as the command's argv[0]
  assert cli.parse(fresh.FLAGS, [name, *argv[4:]], required=("config",)) == [name]  # no positional arguments
  return fresh.FLAGS


def test_gpu_campaigns_lines_parse_with_the_campaign_flags(monkeypatch, tmp_path):
  """The command lines launch/gpu_campaign.py starts parse with the `campaign` command's flags."""
  monkeypatch.chdir(ROOT)  # (the lines name configs/ from the repository's root)
  monkeypatch.syspath_prepend(str(ROOT / "launch"))  # (as when the script runs: its directory first)
  gpu_campaign, gpu_physics = importlib.import_module("gpu_campaign"), importlib.import_module("gpu_physics")
  methods, out = ["soe", "dp", "control"], str(tmp_path / "gpu")
  lines = gpu_campaign.command_lines("lift", 3, methods, "cpu", out)
  started = []  # what `gpu_physics.run_case` would start for each case, caught before it starts
  fake = lambda argv, **kw: started.append(argv) or subprocess.CompletedProcess(argv, 0, "", "")
  monkeypatch.setattr(gpu_physics.subprocess, "run", fake)
  for _, args in gpu_campaign.cases("lift", 3, methods, "cpu", out):
    assert gpu_physics.run_case(args, 60, gpu_campaign.MODULE)["status"] == "ok"
  assert started == lines and len(lines) == len(methods)
  try:
    for line, method in zip(lines, methods):
      assert line[:4] == [sys.executable, "-m", "soe_jax", "campaign"] and line[3] in dispatcher.COMMANDS
      flags = _parsed(monkeypatch, line)
      spec, overrides = flags.config_file()
      assert spec == "configs/lift.py:cpu" and overrides == {"env.backend": "mujoco", "log.videos": 0, "seed": 3}
      config = flags.config
      assert config.seed == 3 and config.env.backend == "mujoco" and config.log.videos == 0
      assert (flags.methods, flags.workdir, flags.results) == ([method], f"{out}/runs", f"{out}/results")
      assert flags.progress is False
      seed, named, configs = campaign_lib.configs(spec, overrides, flags.methods)  # what the campaign would run
      assert seed == 3 and named["seed"] == 3 and [c.seed for c in configs.values()] == [3]
  finally:
    importlib.reload(campaign)  # (unparsed again, for whoever imports it next)
