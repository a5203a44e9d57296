"""Committed records (`results/<study>/*.json`): how a command writes one, and a table per kind. Every
record states its `kind`, first (`write_record`); the records of a study (`studies/`) are tabled by the
study (its `table`, found by its `kind`), the others here:
- `env`, `encoder`, `mjx`: `python -m soe_jax bench env|encoder|mjx --out=...`, a row per record;
- `fit_step`: `python -m soe_jax bench fit --out=...`, the whole policy's fit step, a row per setting;
- `serve`: `python -m soe_jax bench serve`, the policy server's latency per chunk, a row per record;
- `realtime`: `python -m soe_jax bench realtime`, real-time chunks against the blocking loop, a row per
  rate and loop (the table is `bench/realtime.py`'s);
- `memory`: a run's peak memory, measured by `/usr/bin/time -v`;
- `demo_styles`: `python -m soe_jax experts --measure`, how varied each demonstrator's episodes are.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from typing import TYPE_CHECKING

from soe_jax.analysis.studies import registry as studies
from soe_jax.analysis.tables import markdown, pct
from soe_jax.experiment import rundir, runlog, schema
from soe_jax.registry import Registry
from soe_jax.runtime import atomic
from soe_jax.runtime.errors import UserError

if TYPE_CHECKING:
  from soe_jax.experiment import phases

Records = list[tuple[str, dict]]  # (name, record) in file order
TABLES: Registry[Callable[[Records], str]] = Registry("record kind")  # the kinds no study writes


def record(source: dict, exp: phases.Experiment, **parts) -> dict:
  """A study's record from a run of its own: provenance (`source`, taken when the measurement started),
  the shared round 0's directory, the config, then the study's own parts."""
  return dict(source, round0_dir=os.path.basename(exp.dir.round0), config=rundir.plain(exp.config), **parts)


def write_record(result: dict, path: str, kind: str) -> None:
  """The committed record: its kind (which table `results` makes of it, `table`), then provenance, then
  the rest."""
  os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
  atomic.write_json(path, dict(kind=kind, **result))


def differing_settings(config: dict, first: dict) -> str:
  """The settings in which `config` differs from the first record's (or `-`): not its seed, where its
  round 0 lives or how it is logged."""
  a, b = (runlog.flatten(rundir.with_added(c)) for c in (first, config))  # older records lack added fields
  diff = [f"{k}={b.get(k)}" for k in sorted(set(a) | set(b)) if schema.is_setting(k) and a.get(k) != b.get(k)]
  return ", ".join(diff) or "-"


def env_table(records: Records) -> str:
  """`bench env` records (`throughput`), by task, images first, then batch: the batch, the observations,
  the speed, and with images the rendering's share and frames per second, and the renderer (the GL
  pool's processes, or Warp's device)."""
  key = lambda r: (r["throughput"]["task"], r["throughput"]["obs_mode"] != "image", r["throughput"]["num_envs"])
  rows = []
  for r in sorted((r for _, r in records), key=key):
    t = r["throughput"]
    draw = t.get("render")
    frames, share, drawn_by = (
      (f"{draw['frames_per_s']:,.0f}", f"{100 * draw['share']:.0f}%", _renderer(draw)) if draw else ("-", "-", "-")
    )
    rows.append([t["task"], t["num_envs"], t["obs_mode"], f"{t['control_steps_per_s']:,.0f}", frames, share, drawn_by])
  header = [
    "task",
    "environments",
    "observations",
    "control steps/s",
    "frames/s (both cameras)",
    "render share",
    "renderer",
  ]
  return markdown(header, rows)


def _renderer(draw: dict) -> str:
  if draw.get("renderer", "gl") == "gl":
    return f"OpenGL, {draw['processes']} processes"
  return f"Warp on {draw['device']}"


def encoder_table(records: Records) -> str:
  """`bench encoder` records: the trunk, its cost per step against both floors."""
  rows = []
  for _, r in records:
    e = r["encoder"]
    rows.append([
      "/".join(map(str, e["widths"])) + (" (one shared)" if e.get("shared") else ""),
      f"{e['params'] / 1e6:.2f}M",
      f"{e['batch_size']} x {e['n_obs_steps']} x {e['cameras']} ({e['crop']}x{e['crop']} of {e.get('image_size', 84)})",
      f"{e['gflop_per_step']:.1f} / {e['gb_per_step']:.2f}",
      f"{e['step_s']:.2f} s",
      f"{e['flop_floor_s']:.2f} s ({e['matmul_gflops']:.0f} GFLOP/s)",
      f"{e['byte_floor_s']:.2f} s ({e['memory_gbps']:.1f} GB/s)",
      f"{100 * e['fraction_of_floor']:.0f}%",
    ])  # fmt: skip
  header = ["trunk widths", "parameters", "batch x frames x cameras", "GFLOP / GB per step", "step", "FLOP floor",
            "byte floor", "fraction of the higher floor"]  # fmt: skip
  return markdown(header, rows)


def fit_step_table(records: Records) -> str:
  """`bench fit --out` records: the setting (fields differing from the first record's config), the
  parameters, the batch and the fit step."""
  first = records[0][1]["config"]
  rows = []
  for name, r in records:
    f = r["fit_step"]
    rows.append([name, differing_settings(r["config"], first), r["commit"], f"{f['params'] / 1e6:.2f}M",
                 f["batch_size"], f"{f['ms_per_step']:.0f} ms", f"{f['samples_per_s']:.0f}"])  # fmt: skip
  return markdown(["record", "setting", "commit", "parameters", "batch", "fit step", "samples/s"], rows)


def mjx_table(records: Records) -> str:
  """`bench mjx` records: the scene's settings, the checks and their bars, the sizes against the peak."""
  rows = []
  for _, r in records:
    m = r["mjx"]
    settings = ", ".join(f"{k}={v}" for k, v in m["settings"].items()) or "the C engine's"
    ok = "" if m["success_rate"] >= 0.95 and m["path_gap_max_m"] <= 0.01 else " (fails the bar)"
    rows.append([
      m["task"],
      m["impl"],
      settings,
      f"{100 * m['success_rate']:.1f}% ({m['num_episodes']}){ok}",
      f"{m['mean_length']:.1f}",
      f"{1e6 * m['path_gap_max_m']:.1f} / {1e6 * m['path_gap_mean_m']:.1f} µm",
      f"{m['sizes']['contacts']} / {m['peak']['contacts']}",
      f"{m['sizes']['constraints']} / {m['peak']['constraints']}",
      f"{m['path_s']:.0f} s, {m['demos_s']:.0f} s",
    ])  # fmt: skip
  header = ["task", "impl", "MJX settings", "demonstrator success (n)", "mean length",
            "path gap max / mean (50 steps)", "contacts: size / peak", "constraints: size / peak",
            "time (paths, demos)"]  # fmt: skip
  return markdown(header, rows)


def memory_table(records: Records) -> str:
  """A run's peak memory per record: what ran, the peak resident set, the image store, the wall time."""
  rows = [[name, r["what"], f"{r['max_rss_gib']:.2f} GiB", f"{r['image_store_gb']:.2f} GB", f"{r['wall_s']:.0f} s"]
          for name, r in records]  # fmt: skip
  return markdown(["record", "what", "peak resident memory", "image store", "wall time"], rows)


TABLES.register("env", env_table)
TABLES.register("encoder", encoder_table)
TABLES.register("mjx", mjx_table)
TABLES.register("memory", memory_table)


def serve_table(records: Records) -> str:
  """`bench serve` records: the policy, compile time, in-process and round-trip latency (p50 / p95),
  the wire's overhead, the machine."""
  rows = []
  for name, r in records:
    s = r["serve"]
    ms = lambda d: f"{d['p50']:.1f} / {d['p95']:.1f} ms"
    policy = f"{s['task']} {s['obs_encoder']} {s['down_dims']}" + (f", images {s['images']}" if s["images"] else "")
    if s.get("sent", s["images"]) != s["images"]:  # (records before `sent`: the policy's own size)
      policy += f" sent as {s['sent']}"
    rows.append([name, policy, s["requests"], f"{s['compile_s']:.1f} s", ms(s["in_process_ms"]), ms(s["round_trip_ms"]),
                 f"{s['wire_overhead_ms']:.1f} ms", f"{s['request_bytes']:,} B", r["machine"]])  # fmt: skip
  header = ["record", "policy", "requests", "compile", "in-process p50 / p95", "round trip p50 / p95",
            "wire overhead (p50)", "request", "machine"]  # fmt: skip
  return markdown(header, rows)


TABLES.register("serve", serve_table)
TABLES.register("realtime", "soe_jax.bench.realtime:table")


def demo_styles_table(records: Records) -> str:
  """`experts --measure` records: how varied each demonstrator's episodes are (`experts.variety`)."""
  rows = []
  for record_name, r in records:
    arms = r["variety"].get("arms", {"": r["variety"]})  # a two-arm task: a row per arm
    for arm, v in arms.items():
      name = f"{record_name} {arm}".strip()
      met = ", ".join(k for k, ok in v["thresholds_met"].items() if ok) or "none"
      rows.append([name, r["task"], r["style"], f"{pct(v['success_rate'])} of {r['num_episodes']}",
                   f"{pct(v['arc_left'])} / {pct(v['arc_right'])}",
                   f"{pct(v['carry_left'])} / {pct(v['carry_right'])}" if "carry_left" in v else "-",
                   f"{pct(v['face_0'])} / {pct(v['face_1'])}" if "face_0" in v else "-",
                   f"{pct(v['turn_short'])} / {pct(v['turn_long'])}" if "turn_short" in v else "-",
                   f"{v['path_cv']:.3f}", pct(v["paused"]), f"{v['length_mean']:.1f} ± {v['length_std']:.1f}", met,
                   r["commit"]])  # fmt: skip
  header = ["record", "task", "style", "success", "approach arced left / right", "carry arced left / right",
            "faces 0 / 1", "nut turned short / long", "path length CV", "paused",
            "length (steps)", "thresholds met", "commit"]  # fmt: skip
  return markdown(header, rows)


TABLES.register("demo_styles", demo_styles_table)
TABLES.register("fit_step", fit_step_table)


def tables() -> dict[str, Callable[[Records], str]]:
  """Every kind's table: those above and each study's (`studies.registry`), by kind."""
  found = {kind: TABLES.factory(kind) for kind in TABLES.names()}
  found.update({s.kind: s.table for s in studies.studies().values() if s.kind})
  return found


def table(records: Records, folder: str = "") -> str:
  """The table of `records` (from `folder`): all of one kind; a record without a kind is an error
  naming its file, a kind nothing tables one naming the known kinds."""
  known = tables()
  kinds = set()
  for name, r in records:
    if "kind" not in r:
      path = f"{folder.rstrip('/')}/{name}.json" if folder else f"{name}.json"
      raise ValueError(f"{path} states no kind (known kinds: {', '.join(sorted(known))})")
    kinds.add(r["kind"])
  if len(kinds) > 1:
    raise ValueError(f"{folder or 'the records'} holds records of several kinds: {', '.join(sorted(kinds))}")
  kind = kinds.pop()
  if kind not in known:
    raise UserError(f"unknown record kind {kind!r}; known record kinds: {', '.join(sorted(known))}")
  return known[kind](records)
