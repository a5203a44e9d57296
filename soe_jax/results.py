"""Tables from committed results: `results/<study>/*.json`, one record per measured run.

  python -m soe_jax.results results/clean_inputs
  python -m soe_jax.results --docs     # every generated table and figure in README.md and BENCHMARKS.md

A record holds the command, the commit, the machine, the config, and the phase records of what it
measured (`fit`, `evaluate` with the per-state outcomes). The table has a row per record, in file
order, and compares each row with the first on the same evaluation start states (states gained and
lost, McNemar's exact p-value). Records of `python -m soe_jax.bench converge` (with a `check`) get
the convergence table instead: a row per fitting recipe; records of `python -m soe_jax.bench latent`
(with a `latent`) the latent table: effective dimensions and exploration, paired episode by episode
with the first record's; records of `python -m soe_jax.kept` (with `runs`) the kept episodes' table.
A folder of runs a campaign exported (`python -m soe_jax.campaign`) gets the comparison of methods
(`campaign_table`) and the paper's claims tested on it (`soe_jax.claims`), and where its runs have
several rounds the table of rounds and the claim of monotonic improvement (`soe_jax.over_rounds`).

In README.md and BENCHMARKS.md a generated table sits between `<!-- table: RESULTS_DIR -->` and
`<!-- /table -->`; `--docs` rewrites each from its folder, and a test checks that they are current.
`--docs` also draws each figure of rounds named by a line `<!-- figure: RESULTS_DIR PATH.png -->`.
"""

from __future__ import annotations

import glob
import json
import os
import re

import numpy as np
from absl import app, flags

from soe_jax import cli, metrics, over_rounds, runlog

flags.DEFINE_bool("docs", False, "Regenerate every table in README.md and BENCHMARKS.md from its results folder.")
FLAGS = flags.FLAGS


def _pct(x: float) -> str:
  return f"{100 * x:.1f}%"


def table(study: str) -> str:
  paths = sorted(glob.glob(os.path.join(study, "*.json")))
  if not paths:
    from soe_jax import aggregate

    if runs := aggregate.find_runs(study):
      rows = aggregate.rows(runs)
      md = campaign_table(rows) + "\n" + campaign_claims(rows)
      return md + ("\n" + over_rounds.table(rows) if over_rounds.multi_round(rows) else "")
    raise FileNotFoundError(f"no result records (*.json) or exported runs in {study!r}")
  records = [(os.path.basename(p)[:-5], json.load(open(p))) for p in paths]
  if all("runs" in r for _, r in records):  # python -m soe_jax.kept
    from soe_jax import kept

    return kept.table([run for _, r in records for run in r["runs"]])
  if all("throughput" in r for _, r in records):  # python -m soe_jax.bench env --out
    from soe_jax.bench import env

    return env.table(records)
  if all("encoder" in r for _, r in records):  # python -m soe_jax.bench encoder --out
    from soe_jax.bench import encoder

    return encoder.table(records)
  if all("mjx" in r for _, r in records):  # python -m soe_jax.bench mjx
    from soe_jax.bench import mjx

    return mjx.table(records)
  if all("check" in r for _, r in records):
    return convergence_table(records)
  if all("latent" in r for _, r in records):
    groups = {_task_and_size(r["config"]) + (_kl_weight(r["config"]), r["config"].get("seed")) for _, r in records}
    summary = "\n" + effective_dims_table(records) if len(groups) > 1 else ""  # tasks, sizes, KL weights or seeds
    return latent_table(records) + summary
  first = records[0][1]["evaluate"]["success"]
  md = ["| record | inputs | commit | fit (compile) | final loss | success | obs. features out of range | vs first: gained / lost (p) |",
        "|---|---|---|---|---|---|---|---|"]  # fmt: skip
  for name, r in records:
    fit, ev = r["fit"], r["evaluate"]
    c = metrics.paired_comparison(first, ev["success"])
    oor = _pct(ev["obs_out_of_range"]) if "obs_out_of_range" in ev else "-"
    md.append(
      f"| {name} | {r.get('inputs', '-')} | {r['commit']} | {fit['time_total_s']:.0f} s ({fit['time_compile_s']:.0f} s) "
      f"| {fit['final_loss']:.4f} | {_pct(ev['success_rate'])} [{_pct(ev['wilson_low'])}, {_pct(ev['wilson_high'])}] "
      f"(n={ev['num_rollouts']}) | {oor} | {c['gained']} / {c['lost']} (p={c['p_value']:.3f}) |"
    )
  return "\n".join(md) + "\n"


def _setting(config: dict, first: dict) -> str:
  """The fields in which `config` differs from the first record's (or `-`)."""
  from soe_jax import rundir  # (imports MuJoCo: after the command's quiet start)

  a, b = (runlog.flatten(rundir.with_added(c)) for c in (first, config))  # older records lack added fields
  diff = [f"{k}={b.get(k)}" for k in sorted(set(a) | set(b)) if a.get(k) != b.get(k)]
  return ", ".join(diff) or "-"


def convergence_table(records: list[tuple[str, dict]]) -> str:
  """Records of `python -m soe_jax.bench converge`: the setting (fields differing from the first
  record's config), the fit, success along it, and the paired check of continuing it."""
  first = records[0][1]["config"]
  md = ["| record | setting | commit | steps | fit time (with in-fit evaluations) | in-fit success (50 states) | "
        "check: fit -> continued (paired states) | difference [95% CI], p | converged |",
        "|---|---|---|---|---|---|---|---|---|"]  # fmt: skip
  for name, r in records:
    fit, check = r["fit"], r["check"]
    curve = " / ".join(f"{100 * p['success_rate']:.0f}" for p in fit["eval_curve"])
    b, a = check["before"], check["after"]
    md.append(
      f"| {name} | {_setting(r['config'], first)} | {r['commit']} | {fit['steps']:,} | {fit['time_steps_s']:.0f} s "
      f"({fit['time_total_s']:.0f} s) | {curve} | {_pct(b['success_rate'])} -> {_pct(a['success_rate'])} "
      f"(n={b['num_rollouts']}) | {100 * check['difference']:+.1f} [{100 * check['low']:+.1f}, "
      f"{100 * check['high']:+.1f}] pts, p={check['p_value']:.3f} | {'yes' if check['converged'] else 'no'} |"
    )
  return "\n".join(md) + "\n"


def latent_table(records: list[tuple[str, dict]]) -> str:
  """Records of `python -m soe_jax.bench latent`: the setting, round 0's success, the effective dimensions (SNR above the
  threshold, highest first, with the highest SNR), and the exploration, compared episode by episode with
  the first record's of the same task and seed (the same start states and keys; '-' for that record)."""
  first = records[0][1]
  paired = lambda r: (_task_and_size(r["config"])[0], r["config"].get("seed"))
  firsts = {}
  for name, r in records:
    firsts.setdefault(paired(r), name)
  md = ["| record | setting | commit | round-0 success | effective dims (SNR > 0 dB) | highest SNR | posterior variance "
        "E[sigma^2], median over dims | exploration success | Pass@k | jerk | vs the first of its task and seed: "
        "gained / lost (p) |",
        "|---|---|---|---|---|---|---|---|---|---|---|"]  # fmt: skip
  by_name = dict(records)
  for name, r in records:
    lat, ex = r["latent"], r["explore"]
    ref = firsts[paired(r)]
    c = metrics.paired_comparison(by_name[ref]["explore"]["success"], ex["success"])
    vs = "-" if ref == name else f"{c['gained']} / {c['lost']} (p={c['p_value']:.3f})"
    r0 = r.get("round0")  # (records before round 0's evaluation was part of them: '-')
    r0 = "-" if r0 is None else f"{_pct(r0['success_rate'])} (n={r0['num_rollouts']})"
    noise = f"{np.median(lat['noise_db']):.1f} dB" if "noise_db" in lat else "-"  # (recorded since the KL ablation)
    md.append(
      f"| {name} | {_setting(r['config'], first['config'])} | {r['commit']} | {r0} | {len(lat['effective_dims'])} "
      f"{lat['effective_dims']} | {max(lat['snr_db']):.1f} dB | {noise} | {_pct(ex['success_rate'])} [{_pct(ex['wilson_low'])}, "
      f"{_pct(ex['wilson_high'])}] (n={ex['num_rollouts']}) | {_pct(ex['pass_at_k'])} (k={ex['k']}) | {ex['jerk']:.1f} "
      f"| {vs} |"
    )
  return "\n".join(md) + "\n"


# The paper's effective dimensions per task (SNR above 0 dB over the round-0 data).
PAPER_EFFECTIVE_DIMS = {"lift": 8, "can": 8, "square": 10, "transport": 16}


def _task_and_size(config: dict) -> tuple[str, int | None]:
  return config.get("env", {}).get("task", "-"), config["policy"]["bypass"].get("latent_dim")


def _kl_weight(config: dict) -> float:
  return config["policy"]["bypass"]["beta"]


def effective_dims_table(records: list[tuple[str, dict]]) -> str:
  """Latent records of several tasks, latent sizes, KL weights or seeds: per task, latent size d and KL
  weight, the number of effective dimensions per training seed, their mean ± std, and the paper's number
  (which it gives with the KL term only)."""
  groups: dict[tuple, dict] = {}
  for _, r in records:
    key = _task_and_size(r["config"]) + (_kl_weight(r["config"]),)
    groups.setdefault(key, {})[r["config"].get("seed")] = len(r["latent"]["effective_dims"])
  md = ["| task | latent size d | KL weight | seeds | effective dimensions (SNR > 0 dB) per seed | mean ± std | paper |",
        "|---|---|---|---|---|---|---|"]  # fmt: skip
  for (task, d, beta), per_seed in sorted(groups.items()):
    n = [per_seed[k] for k in sorted(per_seed)]
    spread = f"{np.mean(n):.1f} ± {np.std(n, ddof=1):.1f}" if len(n) > 1 else f"{n[0]}"
    seeds = ", ".join(f"seed {k}: {per_seed[k]}" for k in sorted(per_seed))
    paper = PAPER_EFFECTIVE_DIMS.get(task, "-") if beta else "-"
    md.append(f"| {task} | {d} | {beta:g} | {len(n)} | {seeds} | {spread} | {paper} |")
  return "\n".join(md) + "\n"


def _spread(xs, scale: float = 100, unit: str = "%", sign: str = "") -> str:
  """Mean ± sample standard deviation over seeds ('-' if none)."""
  xs = [scale * x for x in xs if x is not None]
  if not xs:
    return "-"
  mean = f"{np.mean(xs):{sign}.1f}"
  return f"{mean} ± {np.std(xs, ddof=1):.1f}{unit}" if len(xs) > 1 else f"{mean}{unit}"


def campaign_table(rows: list[dict]) -> str:
  """A campaign's runs (`aggregate.rows`): the paper's Table I columns, mean ± standard deviation over
  training seeds (Pass@k, jerk, rollouts and the episodes kept, with their mean length where recorded,
  of the first exploration round; success on the evaluation
  states before and after, after also pooled over seeds with its Wilson interval and episode count),
  and each method's last round against its round 0 and against the control of each seed, paired
  state by state (mean difference ± std over seeds; states gained / lost over all seeds; the CMH
  p-value over (seed, state) pairs)."""
  md = ["| task | method | seeds | Pass@5 | avg. jerk (m/s^3) | rollouts | kept (mean length) | success before | "
        "success after (pooled [95% CI], episodes) | relative improvement | vs round 0: difference, gained / "
        "lost, p | vs control: difference, gained / lost, p |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|"]  # fmt: skip
  for r in rows:
    v = r["per_seed"]
    k, n, lo, hi = r["sr_after_pooled"]
    pooled = f"{_spread(v['sr_after'])} ({_pct(k / n)} [{_pct(lo)}, {_pct(hi)}], n={n})" if n else "-"
    kept = _spread(v["kept"], 1, "")
    if kept != "-" and (length := _spread(v["kept_length"], 1, "")) != "-":
      kept += f" ({length} steps)"
    md.append(
      f"| {r['task']} | {r['method']}{r['variant'] and ' (' + r['variant'] + ')'} | {r['seeds']} | "
      f"{_spread(v['pass_at_k'])} | {_spread(v['jerk'], 1, '')} | {_spread(v['rollouts'], 1, '')} | {kept} | "
      f"{_spread(v['sr_before'])} | {pooled} | {_spread(v['improvement_rel'], sign='+')} | {r['vs_round0']} | "
      f"{r['vs_control']} |"
    )
  return "\n".join(md) + "\n"


def campaign_claims(rows: list[dict]) -> str:
  """Per task, the paper's comparative claims that the runs can test (`claims`), one line each."""
  from soe_jax import claims

  lines = []
  for task in sorted({r["task"] for r in rows}):
    lines += [f"- {task}: {c}" for c in claims.claims(rows, task) if ": not measured" not in c]
    if (c := over_rounds.claim(rows, task)) is not None:
      lines.append(f"- {task}: {c}")
  return "\n".join(lines) + "\n"


# A generated table in README.md or BENCHMARKS.md: between these lines, naming its results folder.
_BEGIN = re.compile(r"^<!-- table: (\S+) -->$")
# A generated figure of rounds (`over_rounds.figure`): this line names its results folder and its file.
_FIGURE = re.compile(r"^<!-- figure: (\S+) (\S+) -->$")
_END = "<!-- /table -->"
DOCS = ("README.md", "BENCHMARKS.md")


def regenerate(text: str) -> str:
  """`text` with every generated table replaced by the one its results folder gives now."""
  out, lines, i = [], text.splitlines(keepends=True), 0
  while i < len(lines):
    out.append(lines[i])
    if m := _BEGIN.match(lines[i].rstrip("\n")):
      end = next((j for j in range(i + 1, len(lines)) if lines[j].rstrip("\n") == _END), None)
      begin = next((j for j in range(i + 1, end or len(lines)) if _BEGIN.match(lines[j].rstrip("\n"))), None)
      if end is None or begin is not None:  # an unclosed marker would swallow the text up to the next table's end
        raise ValueError(f"'{lines[i].strip()}' has no '{_END}' after it before the next table")
      out += [table(m.group(1)), lines[end]]
      i = end
    i += 1
  return "".join(out)


def figures(text: str) -> list[str]:
  """Draw every figure of rounds that `text` names (`<!-- figure: RESULTS_DIR PATH -->`); their paths."""
  from soe_jax import aggregate

  drawn = []
  for line in text.splitlines():
    if m := _FIGURE.match(line):
      runs = aggregate.find_runs(m.group(1))
      if not runs:
        raise FileNotFoundError(f"{line.strip()}: no exported runs in {m.group(1)!r}")
      over_rounds.figure(aggregate.rows(runs), m.group(2))
      drawn.append(m.group(2))
  return drawn


def main(argv):
  if FLAGS.docs:
    if len(argv) != 1:
      raise app.UsageError("usage: python -m soe_jax.results --docs (from the repository's root)")
    for path in DOCS:
      old = open(path).read()
      new = regenerate(old)
      if new != old:
        with open(path, "w") as f:
          f.write(new)
      print(f"{path}: {'rewritten' if new != old else 'up to date'}")
      for figure in figures(new):
        print(f"{path}: drew {figure}")
    return
  if len(argv) != 2:
    raise app.UsageError("usage: python -m soe_jax.results RESULTS_DIR | --docs")
  print(table(argv[1]), end="")


if __name__ == "__main__":
  cli.run(main)
