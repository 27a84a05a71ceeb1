"""Self-contained HTML reports: figures inlined as PNG data URIs, tables as HTML.

Used by :class:`skdelay.gap.GapReport` and by ``skdelay analyze``/``demo``; the
page needs no network and no files beside it.
"""

from __future__ import annotations

import base64
import html
import io

import pandas as pd

from ._atomic import write_text

_STYLE = """
body{font-family:system-ui,-apple-system,Segoe UI,sans-serif;max-width:1100px;margin:2em auto;
color:#222;line-height:1.45;padding:0 1em}
h1{border-bottom:2px solid #345;padding-bottom:.2em}h2{margin-top:1.6em;color:#345}
table{border-collapse:collapse;margin:.6em 0;font-size:.92em}
th,td{border:1px solid #ccc;padding:.25em .6em;text-align:right}th{background:#eef2f6}
img{max-width:100%;height:auto;border:1px solid #ddd;margin:.4em 0}
pre{background:#f6f8fa;padding:.8em;overflow-x:auto}
"""


def figure_to_data_uri(fig, *, dpi=100):
    """Render a matplotlib figure to a ``data:image/png;base64,...`` URI."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi, bbox_inches="tight")
    return "data:image/png;base64," + base64.b64encode(buf.getvalue()).decode("ascii")


def _render(item):
    if isinstance(item, pd.DataFrame):
        return item.to_html(float_format=lambda v: f"{v:.4g}", border=0)
    if isinstance(item, pd.Series):
        return item.to_frame().to_html(float_format=lambda v: f"{v:.4g}", border=0)
    if hasattr(item, "savefig"):
        alt = html.escape(item.get_suptitle() or "figure") if hasattr(item, "get_suptitle") else "figure"
        return f'<img alt="{alt}" src="{figure_to_data_uri(item)}">'
    if isinstance(item, str):
        return item  # already HTML
    return f"<pre>{html.escape(str(item))}</pre>"


def render_html(title, sections):
    """Return the HTML text of a report.

    Parameters
    ----------
    title : str
    sections : iterable of (heading, items)
        ``items`` is one item or a list of items; an item is an HTML string, a
        pandas DataFrame/Series (rendered as a table) or a matplotlib Figure
        (inlined as PNG).
    """
    parts = [
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8">',
        f"<title>{html.escape(title)}</title><style>{_STYLE}</style></head><body>",
        f"<h1>{html.escape(title)}</h1>",
    ]
    for heading, items in sections:
        parts.append(f"<section><h2>{html.escape(heading)}</h2>")
        if not isinstance(items, (list, tuple)):
            items = [items]
        parts.extend(_render(item) for item in items)
        parts.append("</section>")
    parts.append("</body></html>")
    return "\n".join(parts)


def write_html(path, title, sections):
    """Write a self-contained HTML report atomically; return the path."""
    return write_text(path, render_html(title, sections))
