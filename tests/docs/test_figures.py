"""The pictures the site shows exist, the copied result figures equal their sources, and drawing the
pictures again gives the same pixels (so they show what the current renderer and game draw)."""

from __future__ import annotations

import re

import numpy as np
import pytest

from modules import load_module

from .markdown_blocks import ROOT, pages

SCRIPT = ROOT / 'docs' / 'tools' / 'docs_figures.py'
IMAGE_LINK = re.compile(r'!\[[^\]]*\]\((?P<target>[^)\s]+)\)')


def _docs_figures():
    return load_module(SCRIPT)


def test_result_figures_are_copies_of_their_sources():
    figures = _docs_figures()
    for name, source in figures.RESULT_FIGURES.items():
        copy = figures.IMAGES / 'results' / name
        assert copy.read_bytes() == (ROOT / source).read_bytes(), (
            f'{copy.relative_to(ROOT)} differs from {source}: run python docs/tools/docs_figures.py results')


def test_gallery_has_one_frame_per_preset():
    import mate
    figures = _docs_figures()
    frames = sorted(path.stem for path in (figures.IMAGES / 'presets').glob('*.png'))
    assert frames == mate.list_presets()


def test_every_image_a_page_shows_exists():
    missing = []
    for page in pages():
        for match in IMAGE_LINK.finditer(page.read_text()):
            target = match['target']
            if not target.startswith(('http://', 'https://')) and not (page.parent / target).is_file():
                missing.append(f'{page.relative_to(ROOT)}: {target}')
    assert not missing


def test_the_gif_is_small():
    figures = _docs_figures()
    assert (figures.IMAGES / 'greedy-play.gif').stat().st_size < 1_000_000


@pytest.mark.parametrize('group', ['presets', 'concepts', 'ranges', 'gif'])
def test_redrawing_gives_the_same_pixels(group, tmp_path, monkeypatch):
    from PIL import Image, ImageSequence
    figures = _docs_figures()
    committed = figures.IMAGES
    monkeypatch.setattr(figures, 'IMAGES', tmp_path)
    drawn = figures.GROUPS[group]()
    assert drawn
    for path in drawn:
        name = path.relative_to(tmp_path)
        with Image.open(path) as new, Image.open(committed / name) as old:
            new_frames = [np.asarray(frame.convert('RGB')) for frame in ImageSequence.Iterator(new)]
            old_frames = [np.asarray(frame.convert('RGB')) for frame in ImageSequence.Iterator(old)]
        assert len(new_frames) == len(old_frames) and all(
            np.array_equal(a, b) for a, b in zip(new_frames, old_frames)), (
            f'docs/images/{name} is stale: run SDL_VIDEODRIVER=dummy python docs/tools/docs_figures.py {group}')
