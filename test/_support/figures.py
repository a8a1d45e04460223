"""What the figure tests look at: every figure a function saves, kept open for a look
(title, legends and where they lie) instead of only the PNG."""
from __future__ import annotations

import contextlib

import matplotlib

matplotlib.use("Agg")
from matplotlib.figure import Figure  # noqa: E402


@contextlib.contextmanager
def saved_figures():
    """Within: each ``Figure.savefig`` also appends (figure, path) to the yielded list,
    drawn so that its text has its place."""
    kept = []
    original = Figure.savefig

    def savefig(fig, path, *args, **kwargs):
        original(fig, path, *args, **kwargs)
        fig.canvas.draw()
        fig._kept_renderer = fig.canvas.get_renderer()     # pyplot.close drops the canvas
        kept.append((fig, str(path)))

    Figure.savefig = savefig
    try:
        yield kept
    finally:
        Figure.savefig = original


def titles(fig) -> list[str]:
    """The figure's title (suptitle) and its axes' titles that are not empty."""
    out = [fig._suptitle.get_text()] if fig._suptitle is not None else []
    out += [t for ax in fig.axes for t in (ax.get_title(), ax.get_title("left"))]
    return [t for t in out if t.strip()]


def legends(fig) -> list:
    """Every legend of the figure: the axes' own, those added as artists, the figure's."""
    out = list(fig.legends)
    for ax in fig.axes:
        if ax.get_legend() is not None:
            out.append(ax.get_legend())
        out += [a for a in ax.artists if isinstance(a, matplotlib.legend.Legend)]
    return out


def overlap(a, b) -> bool:
    """Whether two artists' drawn boxes overlap (in pixels)."""
    r = fig_renderer(a)
    return a.get_window_extent(r).overlaps(b.get_window_extent(r))


def fig_renderer(artist):
    return artist.figure._kept_renderer
