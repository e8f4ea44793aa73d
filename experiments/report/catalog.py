"""What each figure and table of a grid is: its category and caption, for the page and the HTML report.

An output ``figures/<name>.png`` or ``tables/<name>.html`` of a grid is described by
``experiments/report/captions/<name>.rst``: two RST comment lines (not shown) giving its category and a short
title, then the caption in reStructuredText::

    .. category: accuracy
    .. title: RMSE against noise

    The root-mean-square error of each identified frequency ...

``${name}`` placeholders in a caption are filled from the aggregate's context (e.g. ``${longest}``, the grid's
longest record). A figure anyone adds to a grid's ``figures/`` folder is picked up; without a caption file it
lands in the category "other" with a caption saying so. The aggregate writes each filled-in caption beside its
output (``figures/<name>.rst``), which is what the Snakemake report shows (experiments/workflow/rules/report.smk).
"""

from __future__ import annotations

import re
from pathlib import Path
from string import Template

__all__ = ["CAPTIONS", "ORDER", "category_of", "title_of", "caption_of", "sort_key"]

CAPTIONS = Path(__file__).resolve().parent / "captions"
# The order of categories on the grid's page; categories not listed here come after, alphabetically.
ORDER = ("accuracy", "failures", "uncertainty", "scenarios", "tuning", "peers", "paper reproductions", "other")
_META = re.compile(r"^\.\. (category|title):\s*(.+?)\s*$")


def _source(name: str) -> tuple[dict[str, str], str] | None:
    """The metadata and caption body of ``captions/<name>.rst``, or None if there is none."""
    path = CAPTIONS / f"{name}.rst"
    if not path.is_file():
        return None
    meta, body = {}, []
    for line in path.read_text(encoding="utf-8").splitlines():
        m = _META.match(line)
        if m and not body:
            meta[m.group(1)] = m.group(2)
        else:
            body.append(line)
    return meta, "\n".join(body).strip() + "\n"


def category_of(name: str) -> str:
    src = _source(name)
    return src[0].get("category", "other") if src else "other"


def title_of(name: str) -> str:
    src = _source(name)
    return src[0].get("title", name) if src else name


def caption_of(name: str, context: dict | None = None) -> str:
    """The caption of ``name`` in RST, placeholders filled from ``context`` (unknown ones left as they are)."""
    src = _source(name)
    if src is None:
        return (f"``{name}``: no caption written yet (add ``experiments/report/captions/{name}.rst`` with its "
                "category, title and caption).\n")
    return Template(src[1]).safe_substitute({k: str(v) for k, v in (context or {}).items()})


def sort_key(name: str) -> tuple[int, str, str]:
    """Order outputs by category (ORDER first), then by name."""
    cat = category_of(name)
    return (ORDER.index(cat) if cat in ORDER else len(ORDER), cat, name)
