"""A plain HTML report: headings, paragraphs, <img> figures and tables, each table also as CSV.

Formatting only: the numbers arrive in SI; a :class:`Column` says how to show one (scale and
unit label) while the CSV beside the page keeps the SI value under the SI column name.
"""

from __future__ import annotations

import csv
import html
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path


@dataclass(frozen=True)
class Column:
    """A table column: the row key (SI, also the CSV header), its label and display scale."""

    key: str
    label: str
    scale: float = 1.0
    digits: int = 4


@dataclass(frozen=True)
class Table:
    """Rows of a table; written to ``csv_name`` beside the page."""

    title: str
    columns: tuple[Column, ...]
    rows: Sequence[Mapping[str, object]]
    csv_name: str


@dataclass
class Section:
    """One heading with text, figures (paths relative to the page) and tables."""

    title: str
    paragraphs: list[str] = field(default_factory=list)
    figures: list[tuple[str, str]] = field(default_factory=list)  # (file, caption)
    tables: list[Table] = field(default_factory=list)


def format_value(value: object, scale: float = 1.0, digits: int = 4) -> str:
    """A cell as text: numbers scaled to ``digits`` significant digits, NaN as a dash."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if not isinstance(value, int | float):
        return str(value)
    if isinstance(value, int) and scale == 1.0:
        return str(value)
    v = float(value) * scale
    if not math.isfinite(v):
        return "-"
    return f"{v:.{digits}g}"


def _csv_cell(value: object) -> object:
    """A CSV cell: None empty, floats at full precision, booleans ``true``/``false``."""
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    return repr(float(value)) if isinstance(value, float) else value


def write_csv(path: Path, table: Table) -> Path:
    """The table's rows under its SI keys (full precision)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    keys = [c.key for c in table.columns]
    tmp = path.with_name(path.name + ".part")
    with tmp.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(keys)
        for row in table.rows:
            writer.writerow([_csv_cell(row.get(k)) for k in keys])
    os.replace(tmp, path)
    return path


def _table_html(table: Table) -> str:
    head = "".join(f"<th>{html.escape(c.label)}</th>" for c in table.columns)
    body = []
    for row in table.rows:
        cells = "".join(f"<td>{html.escape(format_value(row.get(c.key, ''), c.scale, c.digits))}"
                        "</td>" for c in table.columns)
        body.append(f"<tr>{cells}</tr>")
    link = html.escape(table.csv_name)
    return (f"<h3>{html.escape(table.title)} <small>(<a href=\"{link}\">CSV</a>)</small></h3>\n"
            f"<table>\n<tr>{head}</tr>\n" + "\n".join(body) + "\n</table>")


_STYLE = """body{font-family:sans-serif;max-width:1200px;margin:1em auto;padding:0 1em}
table{border-collapse:collapse;font-size:0.85em;margin-bottom:1em}
td,th{border:1px solid #bbb;padding:2px 6px;text-align:right}
th{background:#eee} img{max-width:100%} pre{background:#f6f6f6;padding:0.5em}
.problems{color:#a00}"""


def write_report(
    out_dir: str | Path,
    title: str,
    summary: str,
    sections: Sequence[Section],
    problems: Sequence[str] = (),
    name: str = "report.html",
) -> Path:
    """Write ``out_dir/name`` and every table's CSV beside it; returns the page's path."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    parts = [f"<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\">"
             f"<title>{html.escape(title)}</title><style>{_STYLE}</style></head><body>",
             f"<h1>{html.escape(title)}</h1>"]
    if problems:
        items = "".join(f"<li>{html.escape(p)}</li>" for p in problems)
        parts.append(f"<h2>Incomplete data</h2><ul class=\"problems\">{items}</ul>")
    parts.append(f"<h2>Summary</h2><pre>{html.escape(summary)}</pre>")
    for section in sections:
        parts.append(f"<h2>{html.escape(section.title)}</h2>")
        parts += [f"<p>{html.escape(p)}</p>" for p in section.paragraphs]
        for file, caption in section.figures:
            src = html.escape(file)
            parts.append(f"<figure><img src=\"{src}\" alt=\"{html.escape(caption)}\">"
                         f"<figcaption>{html.escape(caption)}</figcaption></figure>")
        for table in section.tables:
            write_csv(out / table.csv_name, table)
            parts.append(_table_html(table))
    parts.append("</body></html>\n")
    page = out / name
    tmp = page.with_name(page.name + ".part")
    tmp.write_text("\n".join(parts))
    os.replace(tmp, page)
    return page
