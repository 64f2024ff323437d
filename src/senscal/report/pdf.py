"""PDF from the certificate's HTML with WeasyPrint (no browser).

The HTML carries its own print CSS (A4, ``@page`` margin boxes with the
certificate id and "page x of y", the DRAFT mark); WeasyPrint lays it out and
draws the inline SVG plots as vector graphics.  Rendering is offline: every
resource is inline (``data:`` URIs), and any other URL is refused rather than
fetched, so a certificate never depends on the network.
"""

from __future__ import annotations

import logging
from contextlib import contextmanager
from typing import Iterator

from senscal.errors import InputError

__all__ = ["html_to_pdf"]


def _offline_fetcher(url: str, *args, **kwargs):
    """WeasyPrint URL fetcher that resolves only ``data:`` URIs."""
    if not url.startswith("data:"):
        raise ValueError(f"certificate resources must be inline; refusing to fetch {url[:80]}")
    from weasyprint.urls import default_url_fetcher

    return default_url_fetcher(url, *args, **kwargs)


@contextmanager
def _quiet() -> Iterator[None]:
    """WeasyPrint logs each CSS property it ignores (e.g. screen-only ones); a command's stderr is for warnings."""
    logs = [logging.getLogger(n) for n in ("weasyprint", "weasyprint.progress", "fontTools")]
    levels = [lg.level for lg in logs]
    for lg in logs:
        lg.setLevel(logging.ERROR)
    try:
        yield
    finally:
        for lg, lv in zip(logs, levels):
            lg.setLevel(lv)


def html_to_pdf(html: str) -> bytes:
    """Render a self-contained HTML document to PDF bytes.

    Parameters
    ----------
    html : str
        The document (its ``@page`` CSS decides the paper size and margins).

    Returns
    -------
    bytes
        The PDF file.

    Raises
    ------
    InputError
        WeasyPrint or the libraries it needs (Pango) are not installed: the
        message names the Debian packages.
    """
    try:
        import weasyprint
    except (ImportError, OSError) as exc:
        raise InputError(f"PDF certificates need WeasyPrint and Pango ({exc}); install them (pip install weasyprint; "
                         "Debian: apt-get install libpango-1.0-0 libpangoft2-1.0-0 libharfbuzz-subset0 "
                         "fonts-dejavu-core) or write the certificate as .html") from None
    with _quiet():
        return weasyprint.HTML(string=html, url_fetcher=_offline_fetcher).write_pdf()
