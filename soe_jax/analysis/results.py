"""Tables from committed results: a folder of records (`results/<study>/*.json`, each stating its
`kind`, by which `records.table` finds its table: a study's or one of its own) or of the runs a
campaign exported (`python -m soe_jax campaign`: the comparison of methods, `campaign_table`, the
paper's claims tested on it, `soe_jax.analysis.claims`, and where its runs have several rounds the table of rounds and the claim of
monotonic improvement, `soe_jax.analysis.over_rounds`).

  python -m soe_jax results results/clean_inputs
  python -m soe_jax results --docs     # every generated table and figure in the README, RESULTS.md, BENCHMARKS.md

In those documents a generated table sits between `<!-- table: RESULTS_DIR -->` and `<!-- /table -->`
(`<!-- table: RESULTS_DIR ARM:REFERENCE ... -->` for arms against each other, `against`; `<!-- claims:
RESULTS_DIR ... -->` for the paper's claims over several folders, `<!-- claims-brief: ... -->` for
their verdicts alone); `--docs` (`docs`) rewrites each from its folder, and a test checks that they
are current. `--docs` also draws each figure of rounds named by a line `<!-- figure: RESULTS_DIR
PATH.png -->`.
"""

from __future__ import annotations

import glob
import os
import re

from soe_jax.analysis import against, aggregate, claims, over_rounds, records, seed_level
from soe_jax.analysis import figures as figures_lib
from soe_jax.analysis.tables import markdown, pct, spread
from soe_jax.runtime import atomic


def table(study: str, pairs: list[str] = ()) -> str:
  """The table of the records in folder `study` (by their kind, `records.table`), or of the runs a
  campaign exported there (the comparison of methods, the paper's claims, and over rounds where the
  runs have several); with `pairs` (`ARM:REFERENCE`), the campaign's arms against each other instead
  (`against`)."""
  if pairs:
    if not (runs := aggregate.find_runs(study)):
      raise FileNotFoundError(f"no exported runs in {study!r} to pair")
    return against.table(aggregate.rows(runs), against.parse(pairs))
  paths = sorted(glob.glob(os.path.join(study, "*.json")))
  if not paths:
    if runs := aggregate.find_runs(study):
      rows = aggregate.rows(runs)
      md = campaign_table(rows) + ("\n" + claimed if (claimed := campaign_claims(rows)) else "")
      return md + ("\n" + over_rounds.table(rows) if over_rounds.multi_round(rows) else "")
    raise FileNotFoundError(f"no result records (*.json) or exported runs in {study!r}")
  return records.table([(os.path.basename(p)[:-5], atomic.read_json(p)) for p in paths], study)


def campaign_table(rows: list[dict]) -> str:
  """A campaign's runs (`aggregate.rows`): the paper's Table I columns, mean ± standard deviation over
  training seeds (Pass@k, jerk, rollouts and the episodes kept, with their mean length where recorded,
  of the first exploration round; success on the evaluation
  states before and after, after also pooled over seeds with its Wilson interval and episode count),
  and each method's last round against its round 0 and against the control of each seed, paired
  state by state (mean difference ± std over seeds; states gained / lost over all seeds; the CMH
  p-value over (seed, state) pairs)."""
  out = []
  for r in rows:
    v = r["per_seed"]
    k, n, lo, hi = r["sr_after_pooled"]
    pooled = f"{spread(v['sr_after'])} ({pct(k / n)} [{pct(lo)}, {pct(hi)}], n={n})" if n else "-"
    kept_cell = spread(v["kept"], 1, "")
    if kept_cell != "-" and (length := spread(v["kept_length"], 1, "")) != "-":
      kept_cell += f" ({length} steps)"
    out.append([
      r["task"],
      f"{r['method']}{r['variant'] and ' (' + r['variant'] + ')'}",
      r["seeds"],
      spread(v["pass_at_k"]),
      spread(v["jerk"], 1, ""),
      spread(v["rollouts"], 1, ""),
      kept_cell,
      spread(v["sr_before"]),
      pooled,
      spread(v["improvement_rel"], sign="+"),
      r["vs_round0"],
      r["vs_control"],
    ])  # fmt: skip
  header = ["task", "method", "seeds", "Pass@5", "avg. jerk (m/s^3)", "rollouts", "kept (mean length)", "success before",
            "success after (pooled [95% CI], episodes)", "relative improvement",
            "vs round 0: difference, gained / lost, pooled p", "vs control: difference, gained / lost, pooled p"]  # fmt: skip
  return markdown(header, out)


def campaign_claims(rows: list[dict]) -> str:
  """Per task, the paper's comparative claims that the runs can test (`claims`), one line each ("" if
  none: a control alone tests none)."""
  lines = []
  for task in sorted({r["task"] for r in rows}):
    lines += [f"- {task}: {c}" for c in claims.claims(rows, task) if c.verdict != "not measured"]
    if (c := over_rounds.claim(rows, task)) is not None:
      lines.append(f"- {task}: {c}")
  return "".join(line + "\n" for line in lines)


def claims_summary(folders: list[str], brief: bool = False) -> str:
  """The paper's claims over several campaigns' folders (a task each, or part of one): per claim, a
  line per folder and task with its verdict, its numbers and its training seeds; `brief`, a line per
  claim naming each verdict's tasks and seeds. A folder of several rounds answers the claim over
  rounds alone (its other claims would mix rounds)."""
  found, families = {}, []
  for folder in folders:
    if not (runs := aggregate.find_runs(folder)):
      raise FileNotFoundError(f"no exported runs in {folder!r} for the claims")
    rows = aggregate.rows(runs)
    for task in sorted({r["task"] for r in rows}):
      seeds = max(r["seeds"] for r in rows if r["task"] == task)
      tested = [over_rounds.claim(rows, task)] if over_rounds.multi_round(rows) else claims.claims(rows, task)
      for c in tested:
        if c is not None and c.verdict != "not measured":
          found.setdefault(c.title, []).append((task, f"{seeds} seed{'s' if seeds > 1 else ''}", folder, c))
      if line := family_line(rows, folder, task):
        families.append(line)
  if brief:
    out = []
    for title, tested in found.items():
      verdicts = {}
      for task, seeds, _, c in tested:
        verdicts.setdefault(c.verdict, []).append(f"{task} ({seeds})")
      out.append(f"- {title}: " + "; ".join(f"**{v}** on {', '.join(w)}" for v, w in verdicts.items()) + ".\n")
    return "".join(out)
  head = "- The moderated test's families of success (every fit of the task in the folder but the oracle arms):\n"
  return "".join(
    f"- {title}:\n"
    + "".join(f"  - {task}, {seeds} (`{folder}`): **{c.verdict}**; {c.detail}.\n" for task, seeds, folder, c in tested)
    for title, tested in found.items()
  ) + (head + "".join(f"  - {line}\n" for line in families) if families else "")


def family_line(rows: list[dict], folder: str, task: str) -> str:
  """The family of success of `task` in `folder`'s runs (`rows`, `claims.success_fits`): its fits, its
  degrees of freedom, the seed-to-seed standard deviation of a difference, and the homogeneity check
  (`seed_level.homogeneity` of each fit against the control); "" for a folder of several rounds (its
  family is the rounds') or without a control or a second seed."""
  fits = claims.success_fits(rows, task)
  lay = claims.layout(claims.rates(fits)) if len(fits) > 2 else None
  if over_rounds.multi_round(rows) or lay is None or len(lay.seeds) < 2:
    return ""
  mse, df = seed_level.residual_variance(lay.y)
  h = seed_level.homogeneity(list(claims.against_reference(fits).values()))
  return (
    f"{task} (`{folder}`): {len(lay.names)} fits ({', '.join(lay.names)}) on {len(lay.seeds)} seeds, {df} df; "
    f"seed-to-seed standard deviation of a difference {100 * (2 * mse) ** 0.5:.1f} points; against the "
    f"control, Cochran's Q with no between-seed variance {h['q']:.1f} on {h['df']} df (p = {h['p_value']:.2g}), "
    f"each comparison's Q at the pooled variance: smallest p {h['worst_p']:.2g} (Bonferroni over {h['comparisons']})"
  )


# A generated table in one of `DOCS`: between these lines, naming its results folder (and for a table
# of arms against each other, the pairs); or the paper's claims over several folders (`claims_summary`,
# `-brief` for their verdicts alone), naming them.
_BEGIN = re.compile(r"^<!-- table: (\S+)((?: \S+:\S+)*) -->$")
_CLAIMS = re.compile(r"^<!-- claims(-brief)?: (\S+(?: \S+)*) -->$")
# A generated figure of rounds (`over_rounds.figure`): this line names its results folder and its file;
# or a figure of the claims (`figures.KINDS`): its kind, its arguments (folders, pairs) and its file.
_FIGURE = re.compile(r"^<!-- figure: (\S+) (\S+) -->$")
_FIGURE_KIND = re.compile(r"^<!-- figure (\w+): (\S+(?: \S+)*) (\S+\.png) -->$")
_END = "<!-- /table -->"
DOCS = ("README.md", "RESULTS.md", "BENCHMARKS.md")


def regenerate(text: str) -> str:
  """`text` with every generated table replaced by the one its results folder gives now."""
  out, lines, i = [], text.splitlines(keepends=True), 0
  opens = lambda line: _BEGIN.match(line.rstrip("\n")) or _CLAIMS.match(line.rstrip("\n"))
  while i < len(lines):
    out.append(lines[i])
    if m := opens(lines[i]):
      end = next((j for j in range(i + 1, len(lines)) if lines[j].rstrip("\n") == _END), None)
      begin = next((j for j in range(i + 1, end or len(lines)) if opens(lines[j])), None)
      if end is None or begin is not None:  # an unclosed marker would swallow the text up to the next table's end
        raise ValueError(f"'{lines[i].strip()}' has no '{_END}' after it before the next table")
      made = (
        claims_summary(m.group(2).split(), bool(m.group(1)))
        if m.re is _CLAIMS
        else table(m.group(1), m.group(2).split())
      )
      out += [made, lines[end]]
      i = end
    i += 1
  return "".join(out)


def figure_markers(text: str) -> list[tuple[str, list[str], str]]:
  """The figures of the claims that `text` names: (kind, arguments, path)."""
  return [(m.group(1), m.group(2).split(), m.group(3)) for line in text.splitlines() if (m := _FIGURE_KIND.match(line))]


def figures(text: str) -> list[str]:
  """Draw every figure that `text` names (`<!-- figure: RESULTS_DIR PATH -->` for rounds, `<!-- figure
  KIND: ARGS PATH -->` for the claims' figures, their plotted data beside them); their paths."""
  drawn = []
  for line in text.splitlines():
    if m := _FIGURE.match(line):
      runs = aggregate.find_runs(m.group(1))
      if not runs:
        raise FileNotFoundError(f"{line.strip()}: no exported runs in {m.group(1)!r}")
      over_rounds.figure(aggregate.rows(runs), m.group(2))
      drawn.append(m.group(2))
  for kind, args, path in figure_markers(text):
    if kind not in figures_lib.KINDS:
      raise ValueError(f"unknown figure kind {kind!r}; known: {', '.join(figures_lib.KINDS)}")
    figures_lib.make(kind, args, path)
    drawn.append(path)
  return drawn


def docs() -> list[str]:
  """Regenerate every table of `DOCS` (paths from the repository's root) and draw their figures -> a
  line per document and per figure drawn."""
  lines = []
  for path in DOCS:
    old = open(path).read()
    new = regenerate(old)
    if new != old:
      with open(path, "w") as f:
        f.write(new)
    lines.append(f"{path}: {'rewritten' if new != old else 'up to date'}")
    lines += [f"{path}: drew {figure}" for figure in figures(new)]
  return lines
