"""Exploration strategies side by side from one base policy.

`python -m soe_jax compare` runs it: it fits (or reuses) the config's round-0 policy (with the bypass),
then explores from the same start states with each method's strategy, configured as `python -m soe_jax
run` would run that method (the config file with the method's preset added, then the overrides): each
method's config gives the start states and the tries (`explore.num_start_states`, `explore.tries`: the k
of Pass@k). A table of Pass@k, rollouts, jerk, exploration success and wall time goes to
`<workdir>/compare.md` (+ `.json`).
"""

from __future__ import annotations

import json
import os

from soe_jax.analysis.tables import markdown
from soe_jax.data.episodes import EpisodeSet, build_buffer
from soe_jax.experiment import loop, phases, validation
from soe_jax.experiment.rundir import RunDir
from soe_jax.runtime import atomic, configfile
from soe_jax.runtime.errors import UserError

METHODS = ("dp", "sime", "soe", "soe_steer")


def configs(spec: str, overrides: dict, methods: list[str]) -> dict:
  """{method: the config `configs/<task>.py[:PRESETS]` (`spec`) gives with the method's preset added,
  then `overrides`}, as `python -m soe_jax run` would run that method; an unknown one is a `UserError`."""
  out = {}
  for m in methods:
    try:
      out[m] = configfile.load(spec, m, overrides)
    except ValueError as e:
      raise UserError(f"method {m!r}: {e}") from None
  return out


def compare(configs: dict, workdir: str, progress: bool = True) -> list[dict]:
  """Explore round 1 from the shared round-0 policy with each of `configs` ({method: config}, configs
  that differ only in their method and exploration; each explores its `explore.num_start_states` start
  states `explore.tries` times) -> one row per method. Every config is checked before anything is
  written."""
  for config in configs.values():
    validation.check(config)
  os.makedirs(workdir, exist_ok=True)
  rows, shared = [], None
  for method, config in configs.items():
    config = config.copy_and_resolve_references()
    exp = phases.Experiment(config, RunDir(workdir, config), progress)
    if shared is None:  # round 0, its record and its data: the same for every method
      demos, _, state = loop.round0(exp)
      base = atomic.read_json(exp.dir.phase_path(0, "evaluate"))
      shared = state, build_buffer(config, exp.policy, [EpisodeSet(demos, 0)], exp.env)
    state, buf = shared
    (rec, _, _), times = exp.timed(lambda: exp.explore(state, 1, buf))
    exp.timer.close()
    keys = ("pass_at_k", "rollouts", "rollouts_mean", "jerk", "success_rate")
    rows.append(
      dict(
        method=method,
        strategy=config.explore.strategy.name,
        k=int(config.explore.tries),
        episodes=rec["num_rollouts"],
        wall_s=round(times["time_total_s"], 1),
        compile_s=round(times["time_compile_s"], 1),
        steer_dims=rec.get("steer_dims"),
        steered_fraction=rec.get("steered_fraction"),
        **{k: rec[k] for k in keys},
      )
    )
    print(json.dumps(rows[-1]), flush=True)
  config = next(iter(configs.values()))
  ks = sorted({r["k"] for r in rows})
  pass_at = ks[0] if len(ks) == 1 else "k"  # (methods with different tries: each row says its k)
  cells = []
  for r in rows:
    own_k = "" if len(ks) == 1 else f" (k={r['k']})"
    cells.append([
      r["method"],
      f"{100 * r['pass_at_k']:.0f}%{own_k}",
      f"{r['rollouts']} / {r['rollouts_mean']:.2f}",
      f"{r['jerk']:.1f}",
      f"{100 * r['success_rate']:.1f}% of {r['episodes']}",
      f"{r['wall_s']:.0f} (compile {r['compile_s']:.0f})",
    ])  # fmt: skip
  header = ["Method", f"Pass@{pass_at}", "Rollouts (sum / mean per state)", "Avg. jerk (m/s^3)", "Exploration success",
            "Wall time (s)"]  # fmt: skip
  md = (
    f"Base policy: {config.env.task}, {config.data.num_demos} demonstrations, evaluation success "
    f"{100 * base['success_rate']:.1f}% of {base['num_rollouts']} episodes "
    f"[{100 * base['wilson_low']:.1f}%, {100 * base['wilson_high']:.1f}%].\n\n" + markdown(header, cells)
  )
  with open(os.path.join(workdir, "compare.md"), "w") as f:
    f.write(md)
  atomic.write_json(
    os.path.join(workdir, "compare.json"), dict(base={k: v for k, v in base.items() if k != "success"}, rows=rows)
  )
  print(md, end="")
  return rows
