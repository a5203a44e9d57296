"""One arm of a campaign against another, paired state by state on each seed both ran, in the results
command and in the documents' generated tables."""

import pytest

from soe_jax.analysis import against, aggregate, results
from soe_jax.runtime.errors import UserError
from tests.analysis.test_campaign import _fake_run


@pytest.fixture
def campaign(tmp_path):
  base = [1, 0, 0, 1]
  for seed, soe, aligned in ((0, [1, 0, 0, 0], [1, 1, 1, 0]), (1, [0, 0, 1, 1], [1, 1, 1, 1])):
    _fake_run(tmp_path / f"s{seed}" / "soe", "soe", seed, base, soe)
    _fake_run(tmp_path / f"s{seed}" / "aligned", "soe,aligned=true", seed, base, aligned)
    _fake_run(tmp_path / f"s{seed}" / "control", "control", seed, base, base)
  _fake_run(tmp_path / "s2" / "aligned", "soe,aligned=true", 2, base, base)  # its reference did not run
  return tmp_path


def test_an_arm_is_paired_with_its_reference_on_the_seeds_both_ran(campaign):
  rows = aggregate.rows(aggregate.find_runs(str(campaign)))
  table = against.table(rows, [("soe-aligned", "soe"), ("soe", "control")]).splitlines()
  # seed 0: states 1 and 2 gained; seed 1: states 0 and 1 gained (seed 2 has no soe run)
  assert table[2] == "| lift | soe-aligned | soe | 2 | +50.0 ± 0.0 pts, 4 / 0, p=0.0455 |"
  assert table[3] == "| lift | soe | control | 2 | -12.5 ± 17.7 pts, 1 / 2, p=0.564 |"
  assert len(table) == 4


def test_unknown_methods_and_bad_pairs_are_named(campaign):
  rows = aggregate.rows(aggregate.find_runs(str(campaign)))
  with pytest.raises(UserError, match=r"no method 'dp' in the campaign's runs \(known: control, soe, soe-aligned\)"):
    against.table(rows, [("soe", "dp")])
  with pytest.raises(UserError, match="no method 'dp'"):
    against.table(rows, [("dp", "soe")])
  with pytest.raises(UserError, match="a pair is ARM:REFERENCE"):
    against.parse(["soe-aligned"])


def test_a_documents_table_of_pairs_is_regenerated_from_its_folder(campaign, monkeypatch):
  monkeypatch.chdir(campaign)
  text = "<!-- table: . soe-aligned:soe -->\n| stale |\n<!-- /table -->\n"
  new = results.regenerate(text)
  assert "| lift | soe-aligned | soe | 2 | +50.0 ± 0.0 pts, 4 / 0, p=0.0455 |" in new and "stale" not in new
  assert results.table(".") != results.table(".", ["soe-aligned:soe"])  # without pairs: the campaign's table


def test_a_repeated_seed_is_left_out_naming_the_run_it_repeats(campaign, caplog):
  again = campaign / "t" / "s1" / "control"  # found after s1/control, which it repeats
  _fake_run(again, "control", 1, [1, 0, 0, 1], [0, 0, 0, 0])
  rows = aggregate.rows(aggregate.find_runs(str(campaign)))
  control = next(r for r in rows if r["method"] == "control")
  kept = {run["seed"]: run["workdir"] for run in control["runs"]}
  assert len(control["runs"]) == 2 and kept[1] == str(campaign / "s1" / "control")
  (warning,) = [r.getMessage() for r in caplog.records if "repeats seed" in r.getMessage()]
  assert warning.startswith(f"{again} repeats seed 1 of {campaign / 's1' / 'control'} ")
