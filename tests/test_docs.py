"""The documentation a newcomer reads: the README is short, every file the docs point to exists, and no
tracked file cites a ticket of an issue tracker the reader of the repository does not have."""

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


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_every_repository_file_a_page_names_exists(page):
    names = REPO_PATH.findall(page.read_text(encoding="utf-8"))
    missing = sorted({n for n in names if not (ROOT / n).exists()})
    assert not missing, f"{page.relative_to(ROOT)} names files that do not exist: {missing}"


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
