"""The documentation a newcomer reads: the README is short, states each verdict as it stands (its history
lives in docs/notes/), every file the docs point to exists, and no tracked file cites a ticket of an issue
tracker the reader of the repository does not have."""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README_MAX_LINES = 250

# The pages whose links and file names are checked: the top README, docs/, each family's README.
PAGES = sorted({ROOT / "README.md", *ROOT.glob("docs/**/*.md"), *ROOT.glob("methods/*/README.md"),
                *ROOT.glob("experiments/*/README.md")})
LINK = re.compile(r"\[[^\]]*\]\(([^)\s]+)\)")                        # [text](target)
# A file named in backticks by its path from the repository root, e.g. `methods/pem/_fit.py`; results/ is
# generated, and names with placeholders (<grid>, {akf,wkf}, *) are patterns, not files.
REPO_PATH = re.compile(r"`((?:methods|experiments|configs|docs|tests|profiles)/[\w./-]*\w)`")
# "issue", "Issue" or "issues" followed by a number (with a space, a hyphen or a hash between), or a hash and a
# number alone; not "trial #<n>", an Optuna trial number in the tuned configs.
ISSUE_NUMBER = re.compile(r"\bissues?[ _-]*#?\d+|(?<![\w&])(?<!trial )#\d+\b", re.IGNORECASE)


# A history line: a number as it was ("was 5.6 s", "(first: 50 %"), what came before ("before, 1–62"; "won ...
# before the picker ..., now calls"), a row that says it is out of date ("predate", "out of date"). Plain uses of
# the words ("before any job runs", "what was measured", "the first call") are not history.
HISTORY = re.compile(r"\bwas\s*[\"“(]?[-−~≈<>]?\s*\d|\bwere\s+[-−~≈]?\d|\(first:|\bfirst:\s*[-−~≈]?\d"
                     r"|\bbefore[,:]\s|\bbefore\b[^.|]*\bnow\b|\(now\b|\bpredate|\bout of date\b|\bused to be\b",
                     re.IGNORECASE)


def history_lines(text: str) -> list[str]:
    return [line.strip()[:100] for line in text.splitlines() if HISTORY.search(line)]


def tracked_text_files() -> list[Path]:
    names = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, capture_output=True, check=True).stdout
    files = []
    for name in names.decode().split("\0"):
        path = ROOT / name
        if name and path.is_file():
            try:
                path.read_text(encoding="utf-8")
            except UnicodeDecodeError:
                continue                      # a binary file
            files.append(path)
    return files


def test_readme_is_short_enough_to_read():
    n = len((ROOT / "README.md").read_text(encoding="utf-8").splitlines())
    assert n <= README_MAX_LINES, f"README.md has {n} lines (at most {README_MAX_LINES})"


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_every_relative_link_of_a_page_exists(page):
    text = page.read_text(encoding="utf-8")
    targets = [t.split("#")[0] for t in LINK.findall(text) if not re.match(r"[a-z]+:", t)]
    missing = [t for t in targets if t and not (page.parent / t).exists()]
    assert not missing, f"{page.relative_to(ROOT)} links to missing files: {missing}"
    assert page.name != "README.md" or page.parent != ROOT or targets, "the README links no file"


def heading_anchors(text: str) -> set[str]:
    """The anchors a Markdown renderer gives a page's headings (GitHub's rule: lower case, every character but
    letters, digits, "_", "-" and spaces dropped, spaces to hyphens); fenced code is not a heading."""
    anchors, fenced = set(), False
    for line in text.splitlines():
        if line.startswith("```"):
            fenced = not fenced
        elif not fenced and re.match(r"#{1,6} ", line):
            anchors.add(re.sub(r"[^\w\- ]", "", line.lstrip("#").strip().lower()).replace(" ", "-"))
    return anchors


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_every_section_a_page_links_to_exists(page):
    text = page.read_text(encoding="utf-8")
    missing = []
    for target in LINK.findall(text):
        if "#" not in target or re.match(r"[a-z]+:", target):
            continue
        name, anchor = target.split("#", 1)
        linked = page.parent / name if name else page
        if linked.suffix == ".md" and linked.is_file() and anchor not in heading_anchors(
                linked.read_text(encoding="utf-8")):
            missing.append(target)
    assert not missing, f"{page.relative_to(ROOT)} links to sections that do not exist: {missing}"


@pytest.mark.parametrize(("text", "anchor"), [
    ("## `akf_ambient`, `rpem_ambient`", "akf_ambient-rpem_ambient"),
    ("### The kick test (`split_kicks=true`)", "the-kick-test-split_kickstrue"),
    ("## As shipped, on records unlike the grid's", "as-shipped-on-records-unlike-the-grids"),
    ("```\n# a comment in code\n```", None),
])
def test_heading_anchors_follow_the_renderers_rule(text, anchor):
    assert heading_anchors(text) == ({anchor} if anchor else set())


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_every_repository_file_a_page_names_exists(page):
    names = REPO_PATH.findall(page.read_text(encoding="utf-8"))
    missing = sorted({n for n in names if not (ROOT / n).exists()})
    assert not missing, f"{page.relative_to(ROOT)} names files that do not exist: {missing}"


def test_the_readme_states_each_verdict_as_it_stands():
    found = history_lines((ROOT / "README.md").read_text(encoding="utf-8"))
    assert not found, "history goes to docs/notes/, the README says what holds now:\n" + "\n".join(found)


@pytest.mark.parametrize("line", [
    "2.1 s of CPU with MLflow on, was 5.6 s",
    "agree within 3σ in 100 % of records (was 75 % for mode 2)",
    "covers 64–76 % (first: 50–64 % / 75–86 %)",
    "1 for SSI-cov; before, 1–62.",
    "ERA, which won the short records before the picker asked, now calls them not determined",
    "clipping (now detected; the fit starts after the clip)",
    "The peers' rows predate their picker's confirmation",
    "mode 4 at N = 20 was \"0.0×\" its CRLB",
])
def test_the_history_check_sees_a_history_line(line):
    assert history_lines(line) == [line]


@pytest.mark.parametrize("line", [
    "Bad input gets one line, before any work; nothing is written",
    "options, the choices the paper leaves open, and what was measured.",
    "the first call creates .venv and installs everything",
    "a grid is checked before the DAG is built, each refusal one line",
    "Every method was run at the paper's setting and at a tuned one",
])
def test_the_history_check_leaves_other_lines_alone(line):
    assert history_lines(line) == []


def test_no_tracked_file_names_an_issue_number():
    hits = []
    for path in tracked_text_files():
        for i, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            if ISSUE_NUMBER.search(line):
                hits.append(f"{path.relative_to(ROOT)}:{i}: {line.strip()[:80]}")
    assert not hits, "say what was done, not which ticket asked for it:\n" + "\n".join(hits)


@pytest.mark.parametrize("words", [("see issue", "12"), ("Issue", "9: keep"), ("the issue-", "12 targets"),
                                   ("fixes #", "18"), ("issues", "11 and 13")])
def test_the_issue_pattern_catches_ticket_references(words):
    text = " ".join(words) if not words[0].endswith(("-", "#")) else "".join(words)   # not written whole here
    assert ISSUE_NUMBER.search(text)


@pytest.mark.parametrize("text", ["best trial #58", "a known issue with short records", "§4.3, eq. (31)",
                                  "color #ffaa00", "x[#]"])
def test_the_issue_pattern_leaves_other_text_alone(text):
    assert not ISSUE_NUMBER.search(text)


# ---- a family README describes; its numbers are on the family's benchmark page ------------------------------

FAMILY_READMES = sorted(ROOT.glob("methods/*/README.md"))
# A section or paragraph of measurements: a heading or a bold lead-in that opens with "Measured" ("## Measured
# (the paper grid's ...)", "**Measured on the scoring seed** ...").
MEASURED = re.compile(r"^\s*(?:#+\s*|\*\*)(?:Measured|What was measured)\b", re.IGNORECASE)
# A table or the line that introduces it, saying that its numbers no longer hold.
STALE = re.compile(r"\bout of date\b|\boutdated\b|\bpredates?\b|\bno longer (?:hold|current)|\bstale\b", re.IGNORECASE)


def measured_sections(text: str) -> list[str]:
    return [line.strip()[:100] for line in text.splitlines() if MEASURED.match(line)]


def stale_tables(text: str) -> list[str]:
    """The lines of a table, the line that introduces it and the paragraph that follows it, that say the
    table's numbers are out of date."""
    lines = text.splitlines()
    near = set()
    for i, line in enumerate(lines):
        if not line.lstrip().startswith("|"):
            continue
        near.add(i)
        if i > 0 and not lines[i - 1].lstrip().startswith("|"):
            near.add(i - 1)                          # the line above the table
        if i + 1 < len(lines) and not lines[i + 1].lstrip().startswith("|"):
            k = i + 1 if lines[i + 1].strip() else i + 2         # the paragraph after it
            while k < len(lines) and lines[k].strip() and not lines[k].startswith("#"):
                near.add(k)
                k += 1
    return [lines[i].strip()[:100] for i in sorted(near) if STALE.search(lines[i])]


def test_every_family_has_a_benchmark_page():
    assert {p.parent.name for p in FAMILY_READMES} >= {"kalman", "pem", "pll", "peers", "tracking"}
    missing = [p.parent.name for p in FAMILY_READMES
               if not (ROOT / "docs" / "measured" / f"{p.parent.name}.md").is_file()]
    assert not missing, f"families without a page of numbers under docs/measured/: {missing}"


@pytest.mark.parametrize("readme", FAMILY_READMES, ids=lambda p: str(p.relative_to(ROOT)))
def test_a_family_readme_points_to_its_benchmark_page_for_numbers(readme):
    text = readme.read_text(encoding="utf-8")
    assert f"docs/measured/{readme.parent.name}.md" in text, f"{readme.relative_to(ROOT)} links no page of numbers"
    found = measured_sections(text)
    assert not found, (f"{readme.relative_to(ROOT)}: measurements go to docs/measured/{readme.parent.name}.md, "
                       "the README says what the code does:\n" + "\n".join(found))


@pytest.mark.parametrize("page", [p for p in tracked_text_files() if p.suffix == ".md"],
                         ids=lambda p: str(p.relative_to(ROOT)))
def test_no_table_says_it_is_out_of_date(page):
    found = stale_tables(page.read_text(encoding="utf-8"))
    assert not found, f"{page.relative_to(ROOT)}: rerun the table or drop it:\n" + "\n".join(found)


@pytest.mark.parametrize("text, measured, stale", [
    ("## Measured (the paper grid's 35 cells)\n", True, False),
    ("**Measured on the scoring seed** (`python -m x`):\n", True, False),
    ("**What was measured while building them** (design seed 7)\n", True, False),
    ("The peer rows below predate the picker:\n| a | b |\n|---|---|\n", False, True),
    ("| method | RMSE |\n|---|---|\n| era | 1.2 (out of date) |\n", False, True),
    ("Speed: [docs/measured/kalman.md](../../docs/measured/kalman.md#speed)\n", False, False),
    ("measured in place on a busy machine; the table below is current\n| a |\n", False, False),
    ("| a | b |\n|---|---|\n| 1 | 2 |\n`pem` wins here. The peers'\nrows predate their picker.\n", False, True),
    ("| a |\n|---|\n\nThe peers' rows predate the picker.\n", False, True),
    ("| a |\n|---|\n\n## Next\n\nolder rows predate the picker.\n", False, False),
])
def test_the_family_and_table_checks_see_a_breach(text, measured, stale):
    assert bool(measured_sections(text)) is measured
    assert bool(stale_tables(text)) is stale
