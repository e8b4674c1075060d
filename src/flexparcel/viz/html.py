"""Building blocks of self-contained HTML pages (the reports of :mod:`flexparcel.viz.report`).

A page carries its style inline and its pictures as base64 data URIs, and loads no script:
it opens offline, and mailed on its own it still shows everything but the 3-D viewer it
embeds (``view.html``, a self-contained file of its own next to it, shown in an iframe).
"""

from __future__ import annotations

import base64
import html
import math
from collections.abc import Sequence
from pathlib import Path

__all__ = [
    "NOT_REACHED",
    "esc",
    "number",
    "table",
    "picture",
    "viewer_frame",
    "page",
    "write_page",
]

NOT_REACHED = "not reached in this run"
"""What a report shows for a quantity the run did not measure (never 0)."""

_MIME = {".png": "image/png", ".gif": "image/gif", ".jpg": "image/jpeg"}

_STYLE = """
body { font-family: system-ui, -apple-system, "Segoe UI", sans-serif; margin: 2em auto;
       max-width: 1100px; padding: 0 1em; color: #222; line-height: 1.4; }
h1 { font-size: 1.6em; margin-bottom: 0.2em; } h2 { margin-top: 1.6em; border-bottom:
  1px solid #ccc; } h3 { margin-top: 1.2em; }
.meta { color: #555; font-size: 0.9em; }
table { border-collapse: collapse; margin: 0.6em 0; font-size: 0.92em; }
th, td { border: 1px solid #ccc; padding: 0.25em 0.6em; vertical-align: top; }
th { background: #f2f2f2; text-align: left; } td.num { text-align: right;
  font-variant-numeric: tabular-nums; }
td.missing, span.missing { color: #8a5a00; font-style: italic; }
caption { caption-side: bottom; text-align: left; color: #555; font-size: 0.85em;
  padding-top: 0.3em; }
img { max-width: 100%; height: auto; border: 1px solid #eee; }
.note { background: #fff8e1; border-left: 4px solid #f0b400; padding: 0.5em 0.8em; }
.fail { background: #fdecea; border-left: 4px solid #d93025; padding: 0.5em 0.8em; }
iframe { width: 100%; height: 620px; border: 1px solid #ccc; }
"""


def esc(text: object) -> str:
    """``text`` escaped for HTML."""
    return html.escape(str(text), quote=True)


def number(value: float | None, digits: int = 1, *, why: str = "") -> str:
    """A table cell's HTML: the value with ``digits`` decimals, or :data:`NOT_REACHED` (and
    ``why``) marked as missing, for None and non-finite values alike."""
    if value is None or not math.isfinite(float(value)):
        extra = f" ({esc(why)})" if why else ""
        return f'<span class="missing">{NOT_REACHED}{extra}</span>'
    return f"{float(value):.{digits}f}"


def table(header: Sequence[str], rows: Sequence[Sequence[str]], *, caption: str = "",
          numeric: Sequence[int] = ()) -> str:  # fmt: skip
    """A table; ``header`` is plain text, the ``rows``' cells are HTML (escape text with
    :func:`esc`); columns in ``numeric`` are right-aligned; ``caption`` is HTML."""
    head = "".join(f"<th>{esc(h)}</th>" for h in header)
    body = []
    for row in rows:
        cells = "".join(
            f'<td class="num">{c}</td>' if i in numeric else f"<td>{c}</td>"
            for i, c in enumerate(row)
        )
        body.append(f"<tr>{cells}</tr>")
    cap = f"<caption>{caption}</caption>" if caption else ""
    return f"<table>{cap}<thead><tr>{head}</tr></thead><tbody>{''.join(body)}</tbody></table>"


def picture(path: str | Path, alt: str, *, max_bytes: float = 8e6) -> str:
    """``path`` (PNG, GIF or JPEG) embedded as a data URI; a missing file, or one larger
    than ``max_bytes`` (then linked, relative to the page's folder), is said so in the page
    instead."""
    path = Path(path)
    if not path.is_file():
        return f'<p class="missing">{esc(path.name)}: not written by this run</p>'
    size = path.stat().st_size
    if size > max_bytes:
        return (f'<p><a href="{esc(path.name)}">{esc(path.name)}</a> ({size / 1e6:.1f} MB, '
                "linked, not embedded)</p>")  # fmt: skip
    mime = _MIME.get(path.suffix.lower(), "application/octet-stream")
    data = base64.b64encode(path.read_bytes()).decode("ascii")
    return f'<img alt="{esc(alt)}" src="data:{mime};base64,{data}">'


def viewer_frame(folder: Path, link: str) -> str:
    """The 3-D viewer ``folder/view.html`` in an iframe (``link``: its path relative to the
    page), with a link to open it alone; a sentence where there is none."""
    if not (Path(folder) / "view.html").is_file():
        return ('<p class="missing">view.html: not written (the viewer needs plotly, pip '
                "install 'flexparcel[io]'; flexparcel view DIR writes it later)</p>")  # fmt: skip
    return (f'<p><a href="{esc(link)}">Open the 3-D viewer on its own</a> (play, time '
            "slider, colour by field; drag to turn the camera).</p>"
            f'<iframe src="{esc(link)}" loading="lazy" title="3-D viewer"></iframe>')  # fmt: skip


def page(title: str, body: str, *, subtitle: str = "") -> str:
    """A whole HTML document: ``title`` (text), ``subtitle`` and ``body`` (HTML)."""
    sub = f'<p class="meta">{subtitle}</p>' if subtitle else ""
    return (
        '<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
        '<meta name="viewport" content="width=device-width, initial-scale=1">'
        f"<title>{esc(title)}</title><style>{_STYLE}</style></head>"
        f"<body><h1>{esc(title)}</h1>{sub}{body}</body></html>\n"
    )


def write_page(path: str | Path, text: str) -> Path:
    """Write a page atomically (a reader never sees half a report); returns ``path``."""
    from flexparcel.io.atomic import write_atomic

    return write_atomic(Path(path), text)
