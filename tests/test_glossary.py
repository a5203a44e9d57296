"""The words a newcomer meets first, each explained where it first appears: in the README's paragraph on
the first command, and in the run's own lines."""

import os

import pytest

from soe_jax.experiment import runlog

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

# term -> words of its explanation, found within a few lines after the term's first appearance.
GLOSSARY = {
  "VIB bypass": "latent SOE samples to explore",
  "`train_0.5`": "fewer than half their tries",
  "windows starting at its decisions": "none splices two chunks",
  "observation features out of range": "beyond the demonstrations' span",
}


@pytest.mark.parametrize("term", GLOSSARY)
def test_the_readme_explains_each_term_where_it_first_appears(term):
  text = " ".join(open(os.path.join(ROOT, "README.md")).read().split())
  first = text.index(term)
  assert GLOSSARY[term] in text[max(first - 300, 0) : first + 300], text[first - 300 : first + 300]


def test_a_rollout_phases_line_explains_out_of_range():
  record = dict(round=0, phase="evaluate", success_rate=0.7, num_rollouts=200, wilson_low=0.6, wilson_high=0.8,
                obs_out_of_range=0.003, time_total_s=31.0, time_compile_s=10.0)  # fmt: skip
  line = runlog.summary_line(record)
  assert f"observation features out of range ({GLOSSARY['observation features out of range']}) 0.3%" in line, line
