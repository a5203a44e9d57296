"""Every link into a section of the documents (`[text](RESULTS.md#a-heading)`, `[text](#a-heading)`)
names a file that exists and a heading it has: a renamed heading breaks the README's links to the
results silently otherwise. Every relative link to a file (`[text](docs/guide.md)`, a picture's
`![text](docs/steering.png)`) names one that exists, relative to the document that links it."""

import glob
import os
import re

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DOCS = ("README.md", "RESULTS.md", "BENCHMARKS.md", "DESIGN.md", "docs/*.md")
LINK = re.compile(r"\]\(([^)#\s]*)#([^)\s]+)\)")
FILE_LINK = re.compile(r"\]\(([^)#\s]+)(?:#[^)\s]*)?\)")  # (the file part of a link, its anchor aside)


def anchors(path: str) -> set[str]:
  """The anchors GitHub gives the file's headings: lower case, punctuation but hyphens dropped, spaces
  to hyphens, a repeated heading numbered -1, -2, ...; headings inside code fences are none."""
  out, seen, fenced = set(), {}, False
  for line in open(path):
    fenced ^= line.startswith("```")
    if not fenced and (m := re.match(r"^#{1,6} (.*)$", line.rstrip("\n"))):
      slug = re.sub(r"[^\w\- ]", "", m.group(1).strip().lower()).replace(" ", "-")
      n = seen.get(slug, 0)
      seen[slug] = n + 1
      out.add(slug if n == 0 else f"{slug}-{n}")
  return out


def test_github_anchors_of_headings():
  assert anchors(os.path.join(ROOT, "RESULTS.md")) >= {
    "the-papers-claims-on-the-picked-protocol",  # an apostrophe dropped
    "the-kl-weight-and-aligned-windows-on-new-start-states-lift-3-seeds",  # parentheses dropped
  }


def test_every_link_to_a_section_names_a_heading_of_its_file():
  links, broken = 0, []
  for pattern in DOCS:
    for doc in sorted(glob.glob(os.path.join(ROOT, pattern))):
      for target, anchor in LINK.findall(open(doc).read()):
        links += 1
        path = os.path.normpath(os.path.join(os.path.dirname(doc), target)) if target else doc
        if not os.path.isfile(path) or anchor not in anchors(path):
          broken.append(f"{os.path.relpath(doc, ROOT)}: {target}#{anchor}")
  assert links > 10 and broken == []


def test_every_relative_link_names_a_file_that_exists():
  links, broken = 0, []
  for pattern in DOCS:
    for doc in sorted(glob.glob(os.path.join(ROOT, pattern))):
      for target in FILE_LINK.findall(open(doc).read()):
        if "://" in target or target.startswith("mailto:"):
          continue
        links += 1
        if not os.path.exists(os.path.normpath(os.path.join(os.path.dirname(doc), target))):
          broken.append(f"{os.path.relpath(doc, ROOT)}: {target}")
  assert links > 10 and broken == []
