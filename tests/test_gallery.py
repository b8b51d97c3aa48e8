"""Every figure that the gallery (``docs/gallery.md``) or the README quotes from the demo is
the demo's own: it equals ``docs/images/demo-errors.json``, the ``errors.json`` of the run
that drew the gallery's pictures (``brdfkit demo --gallery docs/images`` copies both).

A quoted figure carries its key in ``errors.json`` right after it, in an HTML comment that
neither GitHub nor Sphinx shows: ``43.0<!-- demo-errors: psnr/blue-metallic-paint/prior 40
-->`` (keys separated by ``/``; the figure is the value rounded to the digits quoted). In
the gallery every decimal number and every figure in dB outside code must carry one; in
the README, every figure in dB or of Delta E in a paragraph that names the demo. So a
figure left unmarked fails here as a figure that disagrees does.

The figures are also those of the built-ins that ship: ``demo-errors.json`` records the
digest of every part that made them (``parts``, ``{built-in: {part: digest}}``), and each
must be the digest the package's manifest records now; a part replaced (retrained and
packed) without the gallery drawn again fails here, and ``brdfkit demo --gallery
docs/images`` is what mends it. Fast (text and JSON only): part of the normal suite, with
no marker.
"""

from __future__ import annotations

import json
import os
import re

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
ERRORS = os.path.join(ROOT, "docs", "images", "demo-errors.json")
QUOTING = {"docs/gallery.md": "every", "README.md": "demo paragraphs"}

MARK = re.compile(r"(-?\d+(?:\.\d+)?)(\s*)<!--\s*demo-errors:\s*(.*?)\s*-->")
ANY_MARK = re.compile(r"<!--\s*demo-errors:.*?-->", re.S)
DECIMAL = re.compile(r"(?<![\w.])\d+\.\d+(?!\.?\d)")
IN_DB = re.compile(r"(?<![\w.])\d+(?:\.\d+)?(?=\s*dB\b)")
DELTA_E = re.compile(r"Delta E(?: 2000)?\D{0,40}?(\d+\.\d+)")


def _prose(text: str) -> str:
    """``text`` without fenced code blocks and inline code (commands, file names)."""
    text = re.sub(r"^```.*?^```", "", text, flags=re.S | re.M)
    return re.sub(r"`[^`\n]*`", "", text)


def quotes(text: str) -> list[tuple[str, list[str]]]:
    """``[(figure as quoted, key path)]`` of the marked figures in ``text``; a marker with
    no figure right before it is an error."""
    prose = _prose(text)
    marks = list(MARK.finditer(prose))
    assert len(marks) == len(ANY_MARK.findall(prose)), "a demo-errors marker without a figure just before it"
    assert all(m.group(2) == "" for m in marks), "a demo-errors marker must follow its figure directly"
    return [(m.group(1), [k.strip() for k in m.group(3).split("/")]) for m in marks]


def unmarked(text: str, scope: str) -> list[str]:
    """Figures of ``text`` that look quoted from the demo but carry no marker: in the
    gallery (``scope`` ``"every"``) decimals and figures in dB; in the README's paragraphs
    that name the demo, figures in dB or of Delta E."""
    out = []
    for para in re.split(r"\n\s*\n", _prose(text)):
        if scope != "every" and "demo" not in para:
            continue
        bare = MARK.sub(" ", para)
        patterns = (DECIMAL, IN_DB) if scope == "every" else (IN_DB, DELTA_E)
        found = {m.span(m.lastindex or 0): m.group(m.lastindex or 0) for p in patterns for m in p.finditer(bare)}
        out += [found[span] for span in sorted(found)]
    return out


def lookup(doc: dict, keys: list[str]):
    value = doc
    for k in keys:
        assert isinstance(value, dict) and k in value, f"demo-errors.json has no {'/'.join(keys)}"
        value = value[k]
    assert isinstance(value, (int, float)) and not isinstance(value, bool), f"{'/'.join(keys)} is not a number"
    return float(value)


def agrees(quoted: str, value: float) -> bool:
    """The value rounded to the digits quoted reads as quoted."""
    digits = len(quoted.split(".")[1]) if "." in quoted else 0
    return f"{value:.{digits}f}" == quoted


@pytest.fixture(scope="module")
def errors() -> dict:
    with open(ERRORS, encoding="utf-8") as f:
        doc = json.load(f)
    assert doc["format"] == "brdfkit-demo-errors"
    return doc


def stale_parts(recorded: dict, manifest) -> list[str]:
    """``built-in/part`` of each part in ``recorded`` (``{built-in: {part: digest}}``) whose
    digest is not the one the manifest (:func:`brdfkit.models.builtin.read_manifest`)
    records, or that it does not list."""
    bundles = {b.name: b for b in manifest.bundles}
    out = []
    for name, parts in sorted(recorded.items()):
        for part, digest in sorted(parts.items()):
            entry = bundles[name].part(part) if name in bundles else None
            if entry is None or entry.digest != digest:
                out.append(f"{name}/{part}")
    return out


def test_the_gallery_was_drawn_with_the_shipped_parts(errors):
    """Every part that made the gallery's figures is the one the package ships: a part
    replaced since needs the gallery drawn again."""
    from brdfkit.models.builtin import read_manifest

    manifest = read_manifest(os.path.join(ROOT, "brdfkit", "models"))
    assert errors.get("parts"), "demo-errors.json records no parts: brdfkit demo --gallery docs/images"
    assert set(errors["parts"]) == {errors["sparse_model"], *errors["compression_models"]}
    assert stale_parts(errors["parts"], manifest) == [], \
        "parts changed since the gallery was drawn: brdfkit demo --gallery docs/images"


def test_a_replaced_part_is_stale():
    from brdfkit.models.builtin import Bundle, Manifest, PartEntry

    manifest = Manifest("m", "a", (Bundle("a", {"basis": PartEntry("b.st", "m/b.st", "1" * 64)}),))
    assert stale_parts({"a": {"basis": "1" * 64}}, manifest) == []
    assert stale_parts({"a": {"basis": "2" * 64}}, manifest) == ["a/basis"]
    assert stale_parts({"a": {"residual": "1" * 64}, "z": {"basis": "1" * 64}}, manifest) == ["a/residual", "z/basis"]


@pytest.mark.parametrize("page", sorted(QUOTING))
def test_every_figure_quoted_from_the_demo_is_its_errors_json(page, errors):
    with open(os.path.join(ROOT, page), encoding="utf-8") as f:
        text = f.read()
    assert unmarked(text, QUOTING[page]) == [], f"{page}: figures without a demo-errors marker"
    wrong = [(q, "/".join(k), lookup(errors, k)) for q, k in quotes(text) if not agrees(q, lookup(errors, k))]
    assert wrong == [], f"{page}: quoted, key, value in docs/images/demo-errors.json"


def test_the_gallery_quotes_what_it_shows():
    """Zero quotes pass only where a page has no figure: the gallery quotes the learnt
    prior's PSNR (and the marker syntax is found where it is used)."""
    with open(os.path.join(ROOT, "docs", "gallery.md"), encoding="utf-8") as f:
        found = quotes(f.read())
    assert found and all(k[0] in ("psnr", "delta_e", "errors", "sheets") for _, k in found)


def test_the_parser_finds_and_checks_figures():
    text = ("From 40 samples (43.0<!-- demo-errors: psnr/m/prior 40 --> dB), 1.5 dB more, 2.25 alone; "
            "`0.25` in code.\n\n```bash\nbrdfkit demo 3.5\n```\n")
    assert quotes(text) == [("43.0", ["psnr", "m", "prior 40"])]
    assert unmarked(text, "every") == ["1.5", "2.25"]
    assert unmarked("The demo: Delta E 2000 of 0.42 and 12 dB.", "demo paragraphs") == ["0.42", "12"]
    assert unmarked("Not that tool: 12 dB.", "demo paragraphs") == []
    doc = {"psnr": {"m": {"prior 40": 42.96}}}
    assert agrees("43.0", lookup(doc, ["psnr", "m", "prior 40"])) and not agrees("42.9", 42.96)
    with pytest.raises(AssertionError, match="no psnr/x"):
        lookup(doc, ["psnr", "x"])
    with pytest.raises(AssertionError, match="without a figure"):
        quotes("text <!-- demo-errors: psnr/m/prior 40 -->")
