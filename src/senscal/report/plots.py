"""Matplotlib helpers that never touch global pyplot state.

Figures are built with :class:`matplotlib.figure.Figure` directly (no GUI
backend, safe in worker processes) and saved as PNG or inlined as SVG.
"""

from __future__ import annotations

import base64
import io
from pathlib import Path

from matplotlib.figure import Figure

__all__ = ["new_figure", "save_figure", "svg_inline", "png_data_uri"]


def new_figure(nrows: int = 1, ncols: int = 1, *, width: float = 8.0, height: float = 4.5, **kw):
    """Return ``(fig, axes)`` without pyplot (``axes`` squeezed like pyplot)."""
    fig = Figure(figsize=(width, height), layout="constrained")
    axes = fig.subplots(nrows, ncols, **kw)
    return fig, axes


def literal_text(fig: Figure) -> Figure:
    """Show every text of ``fig`` literally: no mathtext, so a unit or file name with ``$`` cannot break drawing.

    senscal's own labels use no TeX; user strings (units, channel and file
    names) reach titles and labels, and ``$\\frac{$`` made matplotlib raise.
    """
    from matplotlib.text import Text

    for t in fig.findobj(Text):
        t.set_parse_math(False)
    return fig


def save_figure(fig: Figure, path: str | Path, *, dpi: int = 110) -> Path:
    """Save a figure (format from the extension: .png, .svg, .pdf)."""
    from senscal.io.guard import atomic_output, check_output

    formats = tuple("." + k for k in fig.canvas.get_supported_filetypes())
    path = check_output(path, suffixes=formats, what="plot")
    literal_text(fig)
    with atomic_output(path, what="plot") as tmp:  # no half-written image on a full disk
        fig.savefig(tmp, dpi=dpi, format=path.suffix[1:].lower())
    return path


def svg_inline(fig: Figure) -> str:
    """The figure as an ``<svg>`` element for a self-contained HTML page."""
    buf = io.StringIO()
    literal_text(fig)
    fig.savefig(buf, format="svg")
    text = buf.getvalue()
    return text[text.index("<svg"):]


def png_data_uri(path: str | Path) -> str:
    """A ``data:`` URI for a PNG file, to embed it in HTML."""
    data = Path(path).read_bytes()
    return "data:image/png;base64," + base64.b64encode(data).decode()
