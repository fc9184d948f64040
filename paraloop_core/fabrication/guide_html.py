"""The assembly guide as one HTML page (``assembly.html``) from structured content.

One self-contained file: inline CSS (readable on a phone, printable: steps are not split
across pages), pictures referenced as image files beside it (plain file names only; a tap
opens one at full size), every text HTML-escaped. Sections in order: title and summary,
warnings, facts (size, weight, hardware, print time, the loop and motor, ...), overview
pictures, bill of materials, print settings per profile, parts, numbered assembly steps.
Empty sections are left out.
"""

from __future__ import annotations

import html
import re
from dataclasses import dataclass

from paraloop_core.errors import FabricationError

#: An image beside the page: a plain file name (no folders, no scheme).
_FILE = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.-]*\.(png|jpg|jpeg|gif|webp|svg)")

CSS = """
body{font:16px/1.5 system-ui,-apple-system,"Segoe UI",Roboto,sans-serif;color:#1d1d1f;
 margin:0 auto;max-width:62rem;padding:0 1rem 3rem}
h1{font-size:1.8rem;margin:1.2rem 0 .4rem}h2{font-size:1.35rem;margin:2rem 0 .6rem;
 border-bottom:2px solid #ddd;padding-bottom:.2rem}h3{font-size:1.1rem;margin:1rem 0 .4rem}
figure{margin:.6rem 0}figure img{max-width:100%;height:auto;border:1px solid #e3e3e3;
 border-radius:6px}figcaption{font-size:.9rem;color:#555}
.scroll{overflow-x:auto}table{border-collapse:collapse;margin:.4rem 0;min-width:60%}
th,td{border:1px solid #d6d6d6;padding:.3rem .6rem;text-align:left;vertical-align:top}
th{background:#f3f3f3}td.num{text-align:right;font-variant-numeric:tabular-nums}
.warn{background:#fff4e0;border-left:5px solid #e08a00;padding:.5rem 1rem;margin:1rem 0}
.facts{display:grid;grid-template-columns:max-content 1fr;gap:.2rem 1rem}
.facts dt{font-weight:600}.facts dd{margin:0}
ol.steps{padding-left:0;list-style:none;counter-reset:step}
ol.steps>li{counter-increment:step;border:1px solid #ddd;border-radius:8px;padding:.6rem 1rem;
 margin:1rem 0}
ol.steps>li h3::before{content:"Step " counter(step) ": "}
.note{font-size:.92rem;color:#444}
@media print{body{max-width:none;padding:0}ol.steps>li,figure,table{break-inside:avoid}
 h2{break-after:avoid}a{color:inherit}}
"""


@dataclass(frozen=True)
class Picture:
    """An image file beside the page, its ``alt`` text and an optional ``caption``."""

    file: str
    alt: str
    caption: str = ""


@dataclass(frozen=True)
class Fact:
    """One named value, e.g. ``Fact("size", "157 mm")``."""

    name: str
    value: str


@dataclass(frozen=True)
class BomLine:
    """A line of the bill of materials: ``quantity`` of ``item`` (``note``: where it goes)."""

    item: str
    quantity: str
    note: str = ""


@dataclass(frozen=True)
class PrintProfile:
    """Print settings of one printer or material profile."""

    name: str
    settings: tuple[Fact, ...]


@dataclass(frozen=True)
class PartRow:
    """A printed part: its ``file``, ``plate``, how it lies (``orientation``), the area needing
    support (mm^2, None: not known) and a ``note``."""

    file: str
    plate: str
    orientation: str
    support_mm2: float | None = None
    note: str = ""


@dataclass(frozen=True)
class Step:
    """An assembly step: ``title``, ``text`` (blank lines separate paragraphs), its
    ``pictures`` and ``notes``."""

    title: str
    text: str
    pictures: tuple[Picture, ...] = ()
    notes: tuple[str, ...] = ()


@dataclass(frozen=True)
class Guide:
    """Everything the page says (module docstring)."""

    title: str
    summary: str = ""
    warnings: tuple[str, ...] = ()
    facts: tuple[Fact, ...] = ()
    overview: tuple[Picture, ...] = ()
    bom: tuple[BomLine, ...] = ()
    profiles: tuple[PrintProfile, ...] = ()
    parts: tuple[PartRow, ...] = ()
    steps: tuple[Step, ...] = ()


def _e(text) -> str:
    if not isinstance(text, str):
        raise FabricationError(f"guide text must be a string, got {type(text).__name__}",
                               "bad-parameters")
    return html.escape(text, quote=True)


def _paragraphs(text: str) -> list[str]:
    return [f"<p>{_e(p.strip())}</p>" for p in re.split(r"\n\s*\n", text) if p.strip()]


def _figure(p: Picture) -> str:
    if not isinstance(p.file, str) or not _FILE.fullmatch(p.file):
        raise FabricationError(f"picture file {p.file!r} must be a plain image file name "
                               "(letters, digits, . _ -; .png .jpg .jpeg .gif .webp .svg)",
                               "bad-parameters")
    cap = f"<figcaption>{_e(p.caption)}</figcaption>" if p.caption else ""
    # a tap opens the picture at full size (its labels are small on a phone's screen)
    return f'<figure><a href="{_e(p.file)}"><img src="{_e(p.file)}" alt="{_e(p.alt)}" ' \
           f'loading="lazy"></a>{cap}</figure>'


def _table(head: tuple[str, ...], rows: list[list[tuple[str, bool]]]) -> str:
    """A table with header ``head`` and cells ``(text, numeric)``."""
    th = "".join(f"<th>{_e(h)}</th>" for h in head)
    body = "".join("<tr>" + "".join(f'<td class="num">{_e(t)}</td>' if num else
                                    f"<td>{_e(t)}</td>" for t, num in row) + "</tr>"
                   for row in rows)
    return f'<div class="scroll"><table><thead><tr>{th}</tr></thead><tbody>{body}</tbody>' \
           "</table></div>"


def guide_html(guide: Guide) -> bytes:
    """``assembly.html`` (UTF-8) of ``guide``. Raises :class:`FabricationError`
    (``bad-parameters``) for a text that is not a string or a picture that is not a plain
    image file name."""
    if not isinstance(guide, Guide) or not guide.title.strip():
        raise FabricationError("the guide needs a title", "bad-parameters")
    out = ["<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
           '<meta name="viewport" content="width=device-width, initial-scale=1">',
           f"<title>{_e(guide.title)}</title><style>{CSS}</style></head><body>",
           f"<h1>{_e(guide.title)}</h1>", *_paragraphs(guide.summary)]
    if guide.warnings:
        out.append('<div class="warn"><strong>Before you start</strong><ul>'
                   + "".join(f"<li>{_e(w)}</li>" for w in guide.warnings) + "</ul></div>")
    if guide.facts:
        out.append('<dl class="facts">' + "".join(f"<dt>{_e(f.name)}</dt><dd>{_e(f.value)}</dd>"
                                                  for f in guide.facts) + "</dl>")
    out += [_figure(p) for p in guide.overview]
    if guide.bom:
        out += ["<h2>Bill of materials</h2>", _table(
            ("item", "quantity", "note"),
            [[(b.item, False), (b.quantity, True), (b.note, False)] for b in guide.bom])]
    if guide.profiles:
        out.append("<h2>Print settings</h2>")
        for prof in guide.profiles:
            out += [f"<h3>{_e(prof.name)}</h3>", _table(
                ("setting", "value"), [[(s.name, False), (s.value, False)]
                                       for s in prof.settings])]
    if guide.parts:
        out += ["<h2>Parts to print</h2>", _table(
            ("file", "plate", "orientation", "support (mm²)", "note"),
            [[(p.file, False), (p.plate, True), (p.orientation, False),
              ("–" if p.support_mm2 is None else f"{p.support_mm2:.0f}", True), (p.note, False)]
             for p in guide.parts])]
    if guide.steps:
        out.append('<h2>Assembly</h2><ol class="steps">')
        for s in guide.steps:
            notes = "".join(f'<p class="note">{_e(n)}</p>' for n in s.notes)
            out.append(f"<li><h3>{_e(s.title)}</h3>" + "".join(_paragraphs(s.text))
                       + "".join(_figure(p) for p in s.pictures) + notes + "</li>")
        out.append("</ol>")
    out.append("</body></html>")
    return ("\n".join(out) + "\n").encode("utf-8")
