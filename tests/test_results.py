"""Tables from committed result records compare every row with the first on the same states."""

import json

from soe_jax import results


def _record(success, commit):
  n = len(success)
  ev = dict(success=success, success_rate=sum(success) / n, wilson_low=0.1, wilson_high=0.9, num_rollouts=n)
  fit = dict(time_total_s=10.0, time_compile_s=1.0, final_loss=0.5)
  return dict(commit=commit, inputs="x", fit=fit, evaluate=ev)


def test_table_rows_in_file_order_paired_with_the_first(tmp_path):
  (tmp_path / "01_a.json").write_text(json.dumps(_record([1, 0, 0, 0], "aaa")))
  (tmp_path / "02_b.json").write_text(json.dumps(_record([0, 1, 1, 1], "bbb")))
  rows = results.table(str(tmp_path)).splitlines()[2:]
  assert rows[0].startswith("| 01_a | x | aaa |") and rows[0].endswith("| 0 / 0 (p=1.000) |")
  assert "25.0%" in rows[0] and "75.0%" in rows[1] and rows[1].endswith("| 3 / 1 (p=0.625) |")
