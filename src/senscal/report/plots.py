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

    _plain_tick_labels(fig)
    for t in fig.findobj(Text):
        t.set_parse_math(False)
    return fig


# Digits and minus as superscripts: powers in tick labels and unit symbols without TeX.
SUPERSCRIPT_DIGITS = str.maketrans("0123456789-", "⁰¹²³⁴⁵⁶⁷⁸⁹⁻")


def _pow10(v: float, _pos=None) -> str:
    """``10⁻⁴`` for a power of ten, else the plain number (a log axis' tick label without TeX)."""
    import math

    if v <= 0 or not math.isfinite(v):
        return ""
    e = math.log10(v)
    if abs(e - round(e)) < 1e-9:
        n = int(round(e))
        return f"{v:g}" if -2 <= n <= 3 else "10" + str(n).translate(SUPERSCRIPT_DIGITS)
    return ""


def _plain_tick_labels(fig: Figure) -> None:
    """Tick labels that need no TeX: log axes as ``10⁻⁴`` (their default is mathtext, which literal text
    prints raw as ``$\\mathdefault{10^{-4}}$``) and plain axes without an offset label (``1e-6+5e-2``
    above an axis reads as a typo: the ticks carry the full values instead)."""
    from matplotlib.ticker import FuncFormatter, LogFormatterMathtext, NullFormatter, ScalarFormatter

    for ax in fig.axes:
        for axis in (ax.xaxis, ax.yaxis):
            major = axis.get_major_formatter()
            if isinstance(major, LogFormatterMathtext):
                axis.set_major_formatter(FuncFormatter(_pow10))
                if isinstance(axis.get_minor_formatter(), LogFormatterMathtext):
                    axis.set_minor_formatter(NullFormatter())
            elif isinstance(major, ScalarFormatter):
                major.set_useOffset(False)
                major.set_useMathText(False)


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
