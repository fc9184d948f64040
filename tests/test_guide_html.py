"""assembly.html: every section, step, picture and table row is there; every text escaped."""

from __future__ import annotations

from html.parser import HTMLParser

import pytest

from paraloop_core.errors import FabricationError
from paraloop_core.fabrication.guide_html import (
    BomLine,
    Fact,
    Guide,
    PartRow,
    Picture,
    PrintProfile,
    Step,
    guide_html,
)


class Page(HTMLParser):
    """Tags, image sources, table rows (cells' text) and step titles of a page."""

    def __init__(self):
        super().__init__()
        self.tags: list[str] = []
        self.images: list[tuple[str, str]] = []
        self.tables: list[list[list[str]]] = []
        self.steps: list[str] = []
        self.text: list[str] = []
        self._cell: list[str] | None = None
        self._in_steps = self._in_h3 = False

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        self.tags.append(tag)
        if tag == "img":
            self.images.append((a["src"], a["alt"]))
        elif tag == "table":
            self.tables.append([])
        elif tag == "tr":
            self.tables[-1].append([])
        elif tag in ("td", "th"):
            self._cell = []
        elif tag == "ol" and a.get("class") == "steps":
            self._in_steps = True
        elif tag == "h3" and self._in_steps:
            self._in_h3 = True
            self.steps.append("")

    def handle_endtag(self, tag):
        if tag in ("td", "th"):
            self.tables[-1][-1].append("".join(self._cell))
            self._cell = None
        elif tag == "h3":
            self._in_h3 = False
        elif tag == "ol":
            self._in_steps = False

    def handle_data(self, data):
        self.text.append(data)
        if self._cell is not None:
            self._cell.append(data)
        if self._in_h3:
            self.steps[-1] += data


def parse(page: bytes) -> Page:
    p = Page()
    p.feed(page.decode("utf-8"))
    p.close()
    return p


def example(n_steps: int = 7) -> Guide:
    return Guide(
        title="Assembly of <tv8> & co",
        summary="Six printed links.\n\nThey turn inside out.",
        warnings=("Pins are not retained: glue a washer", "<b>hot</b> nozzle"),
        facts=(Fact("size", "157 mm"), Fact("weight", "9 g PLA"), Fact("print time", "3 h")),
        overview=(Picture("assembly_loop.png", "the loop", "links and joints"),),
        bom=(BomLine("M3 x 20 screw", "6", "one per joint"), BomLine("M3 nyloc nut", "6")),
        profiles=(PrintProfile("PLA", (Fact("layer", "0.2 mm"), Fact("walls", "3"))),
                  PrintProfile("PETG", (Fact("layer", "0.2 mm"),))),
        parts=tuple(PartRow(f"link_{i}.stl", "1", "flat", 12.0 * i if i else None)
                    for i in range(6)),
        steps=tuple(Step(f"joint {k}", f"Slide link {k + 1} onto the pin of link {k}.",
                         (Picture(f"assembly_joint_{k}.png", f"joint {k} exploded"),),
                         ("Turn it by hand.",)) for k in range(n_steps)))


def test_every_step_picture_and_row_is_on_the_page():
    g = example()
    page = parse(guide_html(g))
    assert page.steps == [s.title for s in g.steps]
    assert [src for src, _ in page.images] == \
        ["assembly_loop.png"] + [f"assembly_joint_{k}.png" for k in range(7)]
    bom, pla, petg, part_table = page.tables
    assert bom[1:] == [["M3 x 20 screw", "6", "one per joint"], ["M3 nyloc nut", "6", ""]]
    assert pla[1:] == [["layer", "0.2 mm"], ["walls", "3"]] and petg[1:] == [["layer", "0.2 mm"]]
    assert [r[0] for r in part_table[1:]] == [f"link_{i}.stl" for i in range(6)]
    assert part_table[1][3] == "–" and part_table[2][3] == "12"
    text = "".join(page.text)
    for s in ("157 mm", "9 g PLA", "3 h", "They turn inside out.", "Turn it by hand."):
        assert s in text


def test_text_is_escaped():
    page = parse(guide_html(example()))
    assert "b" not in page.tags and "script" not in page.tags
    text = "".join(page.text)
    assert "Assembly of <tv8> & co" in text and "<b>hot</b> nozzle" in text


def test_empty_sections_are_left_out():
    page = parse(guide_html(Guide(title="t")))
    assert page.tables == [] and page.images == [] and page.steps == []
    assert "ol" not in page.tags


def test_page_is_self_contained_and_for_phones():
    raw = guide_html(example()).decode()
    assert "<style>" in raw and "<link" not in raw and "<script" not in raw
    assert 'name="viewport"' in raw and "@media print" in raw


@pytest.mark.parametrize("name", ["../x.png", "a/b.png", "javascript:alert(1)", ".hidden.png",
                                  "x.exe", "http://host/x.png"])
def test_picture_must_be_a_plain_file_beside_the_page(name):
    with pytest.raises(FabricationError) as err:
        guide_html(Guide(title="t", overview=(Picture(name, "alt"),)))
    assert err.value.reason == "bad-parameters"


def test_non_text_is_refused():
    with pytest.raises(FabricationError):
        guide_html(Guide(title="t", facts=(Fact("size", 3),)))
    with pytest.raises(FabricationError):
        guide_html(Guide(title="  "))


def test_step_titles_and_masses_read_as_words():
    """A step's heading is its first clause (the page numbers the steps itself); small
    parts' masses keep a decimal."""
    from paraloop_core.fabrication import guide

    assert guide.step_title("Joint 0 joins link 0 and link 1: put a washer on") == \
        "Joint 0 joins link 0 and link 1"
    assert guide.step_title("Glue the rod in. Then wait: an hour") == "Glue the rod in"
    long = guide.step_title("word " * 40 + ": x")
    assert len(long) <= guide.TITLE_CHARS + 4 and long.endswith(" ...")
    assert (guide.grams(0.44), guide.grams(12.4), guide.grams(275.2)) == ("0.4", "12", "275")
