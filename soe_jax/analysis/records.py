"""Committed records (`results/<study>/*.json`), a table per kind. Every record states its `kind`, the
command that wrote it sets it (`record.write_record`), and `TABLES` maps a kind to its table:
- `env`, `encoder`, `mjx`: `python -m soe_jax bench env|encoder|mjx --out=...`, a row per record;
- `converge`: `python -m soe_jax converge`, a row per fitting recipe with its paired check;
- `latent`: `python -m soe_jax latent`, effective dimensions and exploration, paired episode by episode
  with the first record's of the same task and seed (and, over several settings or seeds, the
  effective dimensions per seed);
- `kept`: `python -m soe_jax kept`, the kept episodes measured (`kept.table`);
- `round0`: a run's round-0 fit and evaluation (`fit`, `evaluate` with the per-state outcomes), each row
  paired with the first on the same evaluation start states;
- `memory`: a run's peak memory, measured by `/usr/bin/time -v`;
- `serve`: `python -m soe_jax bench serve`, the policy server's latency per chunk, a row per record;
- `fidelity`: `python -m soe_jax fidelity`, the exploration path against the base path (`fidelity.table`);
- `action_range`: `python -m soe_jax action_range`, round 0 on the workspace box against the
  demonstrations' range per distance outside the latter (`action_range.table`);
- `fit_step`: `python -m soe_jax bench fit --out=...`, the whole policy's fit step, a row per setting;
- `calibration`: `python -m soe_jax calibrate`, each test's false-positive rate and power on simulated
  campaigns (`calibration.table`).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from soe_jax import metrics
from soe_jax.analysis import action_range, calibration, fidelity, kept
from soe_jax.analysis.tables import markdown, pct, rate
from soe_jax.experiment import rundir, runlog, schema
from soe_jax.registry import Registry

Records = list[tuple[str, dict]]  # (name, record) in file order
TABLES: Registry[Callable[[Records], str]] = Registry("record kind")
# The paper's effective dimensions per task (SNR above 0 dB over the round-0 data).
PAPER_EFFECTIVE_DIMS = {"lift": 8, "can": 8, "square": 10, "transport": 16}


def _setting(config: dict, first: dict) -> str:
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
    rows.append([name, _setting(r["config"], first), r["commit"], f"{f['params'] / 1e6:.2f}M", f["batch_size"],
                 f"{f['ms_per_step']:.0f} ms", f"{f['samples_per_s']:.0f}"])  # fmt: skip
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


def _against_first(r: dict, first: dict) -> str:
  """A converge record's fit against the first record's on the same check states (same task, evaluation
  seed and count; the sampling keys follow the training seed): difference, gained / lost, p."""
  same = lambda rec: (rec["config"].get("env", {}).get("task"), rec["config"].get("eval", {}).get("seed"),
                      rec["config"].get("seed"))  # fmt: skip
  a, b = first["check"]["before"], r["check"]["before"]
  if r is first or same(r) != same(first) or a["num_rollouts"] != b["num_rollouts"] or "success" not in a:
    return "-"
  c = metrics.paired_comparison(a["success"], b["success"])
  return f"{100 * c['difference']:+.1f} pts, {c['gained']} / {c['lost']} (p={c['p_value']:.2g})"


def converge_table(records: Records) -> str:
  """`converge` records: the setting (fields differing from the first record's config), the fit,
  success along it, the paired check of continuing it, and the fit against the first record's on the
  same check states."""
  first = records[0][1]["config"]
  rows = []
  for name, r in records:
    fit, check = r["fit"], r["check"]
    curve = " / ".join(f"{100 * p['success_rate']:.0f}" for p in fit["eval_curve"])
    b, a = check["before"], check["after"]
    rows.append([
      name,
      _setting(r["config"], first),
      r["commit"],
      f"{fit['steps']:,}",
      f"{fit['time_steps_s']:.0f} s ({fit['time_total_s']:.0f} s)",
      curve,
      f"{pct(b['success_rate'])} -> {pct(a['success_rate'])} (n={b['num_rollouts']})",
      f"{100 * check['difference']:+.1f} [{100 * check['low']:+.1f}, {100 * check['high']:+.1f}] pts, "
      f"p={check['p_value']:.3f}",
      "yes" if check["converged"] else "no",
      _against_first(r, records[0][1]),
    ])  # fmt: skip
  header = ["record", "setting", "commit", "steps", "fit time (with in-fit evaluations)", "in-fit success (50 states)",
            "check: fit -> continued (paired states)", "difference [95% CI], p", "converged",
            "fit against the first record's (paired)"]  # fmt: skip
  return markdown(header, rows)


def _task_and_size(config: dict) -> tuple[str, int | None]:
  return config.get("env", {}).get("task", "-"), config["policy"]["bypass"].get("latent_dim")


def _kl_weight(config: dict) -> float:
  return config["policy"]["bypass"]["beta"]


def _demo_style(config: dict) -> str:
  return config.get("data", {}).get("demo_style", schema.ADDED["data.demo_style"])  # (older records lack it)


def latent_table(records: Records) -> str:
  """`latent` records: the setting, round 0's success, the effective dimensions (SNR above the threshold,
  highest first, with the highest SNR), and the exploration, compared episode by episode with the first
  record's of the same task and seed (the same start states and keys; '-' for that record); over
  several tasks, sizes, KL weights, demonstration styles or seeds, the effective dimensions per seed below."""
  first = records[0][1]
  paired = lambda r: (_task_and_size(r["config"])[0], r["config"].get("seed"))
  firsts = {}
  for name, r in records:
    firsts.setdefault(paired(r), name)
  by_name = dict(records)
  rows = []
  for name, r in records:
    lat, ex = r["latent"], r["explore"]
    ref = firsts[paired(r)]
    c = metrics.paired_comparison(by_name[ref]["explore"]["success"], ex["success"])
    vs = "-" if ref == name else f"{c['gained']} / {c['lost']} (p={c['p_value']:.2g})"
    r0 = r.get("round0")  # (records before round 0's evaluation was part of them: '-')
    r0 = "-" if r0 is None else f"{pct(r0['success_rate'])} (n={r0['num_rollouts']})"
    noise = f"{np.median(lat['noise_db']):.1f} dB" if "noise_db" in lat else "-"  # (recorded since the KL ablation)
    rows.append([
      name,
      _setting(r["config"], first["config"]),
      r["commit"],
      r0,
      f"{len(lat['effective_dims'])} {lat['effective_dims']}",
      f"{max(lat['snr_db']):.1f} dB",
      noise,
      rate(ex),
      f"{pct(ex['pass_at_k'])} (k={ex['k']})",
      f"{ex['jerk']:.1f}",
      vs,
    ])  # fmt: skip
  header = ["record", "setting", "commit", "round-0 success", "effective dims (SNR > 0 dB)", "highest SNR",
            "posterior variance E[sigma^2], median over dims", "exploration success", "Pass@k", "jerk",
            "vs the first of its task and seed: gained / lost (p)"]  # fmt: skip
  groups = {_summary_group(r["config"]) + (r["config"].get("seed"),) for _, r in records}
  summary = "\n" + effective_dims_table(records) if len(groups) > 1 else ""  # several groups or seeds
  return markdown(header, rows) + summary


def _summary_group(config: dict) -> tuple:
  return _task_and_size(config) + (_kl_weight(config), _demo_style(config))


def effective_dims_table(records: Records) -> str:
  """Latent records of several tasks, latent sizes, KL weights, demonstration styles or seeds: per task,
  latent size d, KL weight and demonstration style, the number of effective dimensions per training seed,
  their mean ± std, and the paper's number (which it gives with the KL term only)."""
  groups: dict[tuple, dict] = {}
  for _, r in records:
    groups.setdefault(_summary_group(r["config"]), {})[r["config"].get("seed")] = len(r["latent"]["effective_dims"])
  rows = []
  for (task, d, beta, style), per_seed in sorted(groups.items()):
    n = [per_seed[k] for k in sorted(per_seed)]
    spread = f"{np.mean(n):.1f} ± {np.std(n, ddof=1):.1f}" if len(n) > 1 else f"{n[0]}"
    seeds = ", ".join(f"seed {k}: {per_seed[k]}" for k in sorted(per_seed))
    paper = PAPER_EFFECTIVE_DIMS.get(task, "-") if beta else "-"
    rows.append([task, d, f"{beta:g}", style, len(n), seeds, spread, paper])
  header = ["task", "latent size d", "KL weight", "demonstrations", "seeds",
            "effective dimensions (SNR > 0 dB) per seed", "mean ± std", "paper"]  # fmt: skip
  return markdown(header, rows)


def round0_table(records: Records) -> str:
  """A run's round 0 per record (`fit`, `evaluate`), each paired with the first record's evaluation."""
  first = records[0][1]["evaluate"]["success"]
  rows = []
  for i, (name, r) in enumerate(records):
    fit, ev = r["fit"], r["evaluate"]
    c = metrics.paired_comparison(first, ev["success"])
    rows.append([
      name,
      r.get("inputs", "-"),
      r["commit"],
      f"{fit['time_total_s']:.0f} s ({fit['time_compile_s']:.0f} s)",
      f"{fit['final_loss']:.4f}",
      rate(ev),
      pct(ev["obs_out_of_range"]) if "obs_out_of_range" in ev else "-",
      f"{c['gained']} / {c['lost']} (p={c['p_value']:.2g})" if i else "-",
    ])  # fmt: skip
  header = ["record", "inputs", "commit", "fit (compile)", "final loss", "success", "obs. features out of range",
            "vs first: gained / lost (p)"]  # fmt: skip
  return markdown(header, rows)


def memory_table(records: Records) -> str:
  """A run's peak memory per record: what ran, the peak resident set, the image store, the wall time."""
  rows = [[name, r["what"], f"{r['max_rss_gib']:.2f} GiB", f"{r['image_store_gb']:.2f} GB", f"{r['wall_s']:.0f} s"]
          for name, r in records]  # fmt: skip
  return markdown(["record", "what", "peak resident memory", "image store", "wall time"], rows)


TABLES.register("env", env_table)
TABLES.register("encoder", encoder_table)
TABLES.register("mjx", mjx_table)
TABLES.register("converge", converge_table)
TABLES.register("latent", latent_table)
TABLES.register("kept", lambda records: kept.table([run for _, r in records for run in r["runs"]]))
TABLES.register("round0", round0_table)
TABLES.register("memory", memory_table)


def serve_table(records: Records) -> str:
  """`bench serve` records: the policy, compile time, in-process and round-trip latency (p50 / p95),
  the wire's overhead, the machine."""
  rows = []
  for name, r in records:
    s = r["serve"]
    ms = lambda d: f"{d['p50']:.1f} / {d['p95']:.1f} ms"
    policy = f"{s['task']} {s['obs_encoder']} {s['down_dims']}" + (f", images {s['images']}" if s["images"] else "")
    rows.append([name, policy, s["requests"], f"{s['compile_s']:.1f} s", ms(s["in_process_ms"]), ms(s["round_trip_ms"]),
                 f"{s['wire_overhead_ms']:.1f} ms", f"{s['request_bytes']:,} B", r["machine"]])  # fmt: skip
  header = ["record", "policy", "requests", "compile", "in-process p50 / p95", "round trip p50 / p95",
            "wire overhead (p50)", "request", "machine"]  # fmt: skip
  return markdown(header, rows)


TABLES.register("serve", serve_table)


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
TABLES.register("fidelity", lambda records: fidelity.table([run for _, r in records for run in r["runs"]]))
TABLES.register("action_range", lambda records: action_range.table([s for _, r in records for s in r["seeds"]]))
TABLES.register("fit_step", fit_step_table)
TABLES.register("calibration", lambda records: calibration.table([r for _, r in records]))


def table(records: Records, folder: str = "") -> str:
  """The table of `records` (from `folder`): all of one kind; a record without a kind is an error naming
  its file."""
  kinds = set()
  for name, r in records:
    if "kind" not in r:
      path = f"{folder.rstrip('/')}/{name}.json" if folder else f"{name}.json"
      raise ValueError(f"{path} states no kind (known kinds: {', '.join(TABLES.names())})")
    kinds.add(r["kind"])
  if len(kinds) > 1:
    raise ValueError(f"{folder or 'the records'} holds records of several kinds: {', '.join(sorted(kinds))}")
  return TABLES.make(kinds.pop(), records)
