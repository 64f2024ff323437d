"""The Typer application objects that command modules attach to.

Command modules live beside this file as ``cmd_*.py``; each imports ``app``
(or ``simulate_app``) from here and registers its commands.  They are found
and imported by :func:`senscal.cli.load_commands`, so adding a job never
means editing a shared list.
"""

from __future__ import annotations

import typer

app = typer.Typer(
    name="senscal",
    help="Calibrate sensors and correct their errors.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    # Plain Click help (grouped by panel in senscal.cli._help): no Rich import to print it, same text in a pipe.
    rich_markup_mode=None,
)

simulate_app = typer.Typer(
    help="Write simulated recordings with known truth (truth JSON beside them).",
    no_args_is_help=True,
)
app.add_typer(simulate_app, name="simulate")
