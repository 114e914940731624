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


def save_figure(figure, path, dpi: int = 110) -> Path:
    """Lay out `figure`, write it to `path` (parents created) and close it; returns the path."""
    import matplotlib.pyplot as plt

    figure.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(path, dpi=dpi)
    plt.close(figure)
    return path
