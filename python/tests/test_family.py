"""Families from Python: the built-ins, rendering and printable sheets."""

import numpy as np
import pytest

import tagsmith


def test_every_built_in_family_loads_and_renders():
    names = tagsmith.families()
    assert "apriltag-36h11" in names and "runetag" in names
    assert set(tagsmith.detectable_families()) <= set(names)
    for name in names:
        family = tagsmith.Family.load(name)
        image = family.render(0, 64)
        assert image.dtype == np.uint8 and image.shape[1] == 64
        assert image.min() < 80 and image.max() > 180, name
        assert isinstance(family.validate(), list)
    assert tagsmith.Family.load("apriltag-36h11").has_shipped_weights
    assert tagsmith.Family.load("runetag").has_shipped_weights
    assert not tagsmith.Family.load("runetag-plus").has_shipped_weights


def test_render_refuses_an_unknown_id():
    family = tagsmith.Family.load("aruco-4x4_50")
    assert family.size == 50
    with pytest.raises(ValueError, match="49"):
        family.render(50)


def test_sheets_are_written_as_pdf_and_svg_pages(tmp_path):
    family = tagsmith.Family.load("apriltag-36h11")
    [pdf] = family.sheet(list(range(12)), tmp_path / "sheet.pdf", cut_marks=True)
    assert pdf.read_bytes().startswith(b"%PDF")
    pages = family.sheet(list(range(60)), tmp_path / "many.svg", marker_side_mm=40)
    assert len(pages) > 1
    assert all(p.read_text().lstrip().startswith("<svg") or "<svg" in p.read_text() for p in pages)
    with pytest.raises(ValueError, match="sheet.png"):
        family.sheet([0], tmp_path / "sheet.png")
    with pytest.raises(ValueError, match="page"):
        family.sheet([0], tmp_path / "x.pdf", page="A9")
