"""Figures as PNG files with matplotlib's Agg backend (no display needed): the one place that selects it."""

from __future__ import annotations

from pathlib import Path

__all__ = ['pyplot', 'save_figure']


def pyplot():
    """`matplotlib.pyplot` on the Agg backend."""
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    return plt


def save_figure(figure, path, dpi: int = 110, layout: bool = True, palette: int | None = None) -> Path:
    """Lay out `figure` (`layout=False`: as it is placed), write it to `path` (parents created) and close it; returns
    the path. `palette`: write the PNG with an adaptive palette of that many colours (a few times fewer bytes, for
    figures a repository carries)."""
    import matplotlib.pyplot as plt

    if layout:
        figure.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(path, dpi=dpi)
    plt.close(figure)
    if palette:
        from PIL import Image

        with Image.open(path) as image:
            small = image.convert('RGB').quantize(colors=palette, method=Image.Quantize.MAXCOVERAGE)
        small.save(path, optimize=True)
    return path
