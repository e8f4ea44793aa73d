"""Tables as standalone HTML pages, so the Snakemake report can show them (it shows HTML, not CSV/Markdown).

pandas renders each table (``DataFrame.to_html``, cells escaped); this module only wraps them in one page
with a heading per table and a little CSS, and writes it through experiments.io.
"""

from __future__ import annotations

import html
from pathlib import Path

import numpy as np
import pandas as pd

from experiments.io import atomic_write_text

__all__ = ["render", "write"]

_CSS = ("body{font-family:sans-serif;font-size:13px;margin:1em}"
        "table{border-collapse:collapse;margin:0.5em 0 1.5em}"
        "th,td{border:1px solid #ccc;padding:2px 6px;text-align:right}"
        "th{background:#f0f0f0}tr:nth-child(even) td{background:#fafafa}"
        "pre{white-space:pre-wrap;background:#f8f8f8;padding:0.5em}")


def _fmt(v) -> str:
    if isinstance(v, float | np.floating):
        return "" if np.isnan(v) else format(float(v), ".4g")
    return str(v)


def render(title: str, sections: list[tuple[str, pd.DataFrame | str]]) -> str:
    """One HTML page: ``title``, then per section its heading and a table (DataFrame) or text (str, as is)."""
    parts = [f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{html.escape(title)}</title>"
             f"<style>{_CSS}</style></head><body><h1>{html.escape(title)}</h1>"]
    for heading, content in sections:
        if heading:
            parts.append(f"<h2>{html.escape(heading)}</h2>")
        if isinstance(content, pd.DataFrame):
            parts.append(content.to_html(index=False, na_rep="", formatters={
                c: _fmt for c in content.columns}, border=0))
        else:
            parts.append(f"<pre>{html.escape(str(content))}</pre>")
    parts.append("</body></html>\n")
    return "\n".join(parts)


def write(path: Path, title: str, sections: list[tuple[str, pd.DataFrame | str]]) -> Path:
    return atomic_write_text(path, render(title, sections))
