"""Tables never elide a number: at 80 columns (or a pipe) wide tables stack."""

from __future__ import annotations

import io

from rich.console import Console

from senscal.cli.common import table


def _render(tab, width: int) -> str:
    buf = io.StringIO()
    Console(file=buf, width=width, force_terminal=False, color_system=None).print(tab)
    return buf.getvalue()


def test_wide_table_stacks_every_digit_at_80_columns():
    cols = ["channel", "frequency (Hz)", "amplitude", "U amplitude", "phase (deg)", "U phase", "offset", "U offset",
            "residual RMS", "SNR dB"]
    rows = [["ch1 [V]", 12.5, 2.80424123, 0.00318522, 162.18042, 0.0650797, -1.42408, 0.00225229, 0.0503249, 31.9]]
    out = _render(table("Sine fit", cols, rows), 80)
    assert "…" not in out and "..." not in out
    for v in ("2.80424", "0.00318522", "162.18", "-1.42408", "0.0503249", "ch1 [V]"):
        assert v in out
    assert all(len(line) <= 80 for line in out.splitlines())


def test_table_that_fits_stays_a_table():
    out = _render(table("t", ["name", "value"], [["a", 1.5], ["b", 2.25]]), 80)
    assert "┃" in out or "│" in out
    assert "1.5" in out and "2.25" in out
