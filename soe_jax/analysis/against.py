"""One arm of a campaign against another, paired state by state on each seed's last round: the
comparisons a decision rule names beyond "against the control" (an arm against the same method without
its setting, a relabelled arm against the arm whose states it took). In RESULTS.md such a table is
`<!-- table: RESULTS_DIR ARM:REFERENCE ... -->`, one pair per row, over the seeds both arms ran."""

from __future__ import annotations

from soe_jax.analysis import aggregate
from soe_jax.analysis.tables import markdown
from soe_jax.runtime.errors import UserError


def parse(pairs: list[str]) -> list[tuple[str, str]]:
  """['soe-aligned:soe', ...] -> [('soe-aligned', 'soe'), ...]."""
  out = []
  for p in pairs:
    arm, sep, ref = p.partition(":")
    if not (sep and arm and ref):
      raise UserError(f"{p!r}: a pair is ARM:REFERENCE, two method names of the campaign")
    out.append((arm, ref))
  return out


def table(rows: list[dict], pairs: list[tuple[str, str]]) -> str:
  """For each (arm, reference) of one task's campaign rows (`aggregate.rows`, variant ''): the arm's
  last round against the reference's on the seeds both ran: mean difference ± std over seeds, states
  gained / lost, the pooled CMH p-value (as the campaign table's comparisons are)."""
  by = {(r["task"], r["method"]): r for r in rows if not r["variant"]}
  known = ", ".join(sorted({m for _, m in by}))
  last = lambda run: run["outcomes"]["evaluate"].get(run["last"])  # its last round's per-state outcomes
  out = []
  for arm, ref in pairs:
    tasks = sorted(t for t, m in by if m == arm)
    missing = arm if not tasks else next((ref for t in tasks if (t, ref) not in by), None)
    if missing:
      raise UserError(f"no method {missing!r} in the campaign's runs (known: {known})")
    for task in tasks:
      refs = {run["seed"]: run for run in by[task, ref]["runs"]}
      pairs_ = [(last(refs[run["seed"]]), last(run)) for run in by[task, arm]["runs"] if run["seed"] in refs]
      c = aggregate.comparison(pairs_)
      out.append([task, arm, ref, c["seeds"] if c else 0, aggregate.paired_cell(c)])
  return markdown(["task", "arm", "against", "seeds", "difference, gained / lost, pooled p"], out)
