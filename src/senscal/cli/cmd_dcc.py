"""``senscal dcc verify FILE.xml``: check a Digital Calibration Certificate's schema and signature."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer
from typing_extensions import Annotated

from senscal.cli.app import app
from senscal.cli.common import JsonOpt, console, print_json
from senscal.errors import InputError

dcc_app = typer.Typer(help="Digital Calibration Certificates: verify a signed DCC.", no_args_is_help=True)
app.add_typer(dcc_app, name="dcc")


def _read(path: Path, what: str) -> bytes:
    try:
        return Path(path).read_bytes()
    except OSError as exc:
        raise InputError(f"{what} {path}: cannot read it ({exc.strerror or exc}); give the file's path") from None


@dcc_app.command("verify")
def verify_cmd(
    file: Annotated[Path, typer.Argument(help="The DCC (.xml) to check.")],
    cert: Annotated[Optional[Path], typer.Option(
        "--cert", metavar="CERT.pem", help="The signer's certificate (PEM) the signature must be by; without it the "
                                           "certificate in the signature proves integrity, not who signed.")] = None,
    json_out: JsonOpt = False,
) -> None:
    """Check a DCC against the DCC 3.1.2 schema and its XML signature: exit 0 valid, exit 3 naming what fails."""
    from senscal.report.signing import verify_dcc

    data = _read(file, "DCC")
    if not data.lstrip().startswith(b"<"):
        raise InputError(f"{file} is not an XML file; give a DCC written with --dcc")
    check = verify_dcc(data, None if cert is None else _read(cert, "--cert"))
    if json_out:
        print_json({"file": str(file), "valid": True, **check.to_dict()})
        return
    who = check.signer if check.certificate_pinned else f"{check.signer} (the embedded certificate: give --cert to " \
                                                         "check who signed)"
    console.print(f"{file}: valid (DCC schema, signature by {who}, signed {check.signing_time or 'at an unstated time'})",
                  markup=False, soft_wrap=True)
