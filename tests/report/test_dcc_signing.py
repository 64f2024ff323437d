"""Signed DCCs: an enveloped XAdES signature that keeps the DCC schema-valid, and ``senscal dcc verify`` that
passes a valid one (exit 0) and names what fails when a value or the signature was changed (exit 3)."""

from __future__ import annotations

import datetime as dt
import re
from dataclasses import replace

import pytest

pytest.importorskip("signxml")

from senscal.errors import InputError
from senscal.report.dcc import dcc_xml, validate_dcc
from senscal.report.lab import CertificateInfo, Condition, LabProfile, Person, RunInfo, Standard
from senscal.report.signing import SignatureInvalid, sign_dcc, verify_dcc


def _keypair(tmp, name="lab", kind="rsa", days=30):
    """A throw-away self-signed certificate and its key, as PEM files."""
    from cryptography import x509
    from cryptography.hazmat.primitives import hashes, serialization
    from cryptography.hazmat.primitives.asymmetric import ec, rsa
    from cryptography.x509.oid import NameOID

    key = (rsa.generate_private_key(public_exponent=65537, key_size=2048) if kind == "rsa"
           else ec.generate_private_key(ec.SECP256R1()))
    subject = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, f"{name} signer")])
    now = dt.datetime.now(dt.timezone.utc)
    cert = (x509.CertificateBuilder().subject_name(subject).issuer_name(subject).public_key(key.public_key())
            .serial_number(x509.random_serial_number()).not_valid_before(now - dt.timedelta(days=40))
            .not_valid_after(now + dt.timedelta(days=days)).sign(key, hashes.SHA256()))
    k, c = tmp / f"{name}-key.pem", tmp / f"{name}-cert.pem"
    k.write_bytes(key.private_bytes(serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8,
                                    serialization.NoEncryption()))
    c.write_bytes(cert.public_bytes(serialization.Encoding.PEM))
    return k, c


@pytest.fixture(scope="module")
def keys(tmp_path_factory):
    d = tmp_path_factory.mktemp("keys")
    return {"lab": _keypair(d, "lab"), "other": _keypair(d, "other"), "ec": _keypair(d, "ec", kind="ec")}


@pytest.fixture(scope="module")
def dcc():
    from senscal.simulate.vibration import simulate_centrifuge
    from senscal.vibration import frequency_response, response_point

    recs, _ = simulate_centrifuge(frequencies=(1.0, 5.0), seed=3, min_duration=3.0)
    pts = [response_point(r["output"], r.time, input_amplitude=100.0, angle_deg=r["angle"], static_sensitivity=0.05,
                          u_input=0.002, initial_phase=0.0, u_input_phase=1e-4, source=f"rec{i}.csv")
           for i, r in enumerate(recs)]
    resp = frequency_response(pts, static_sensitivity=0.05)
    lab = LabProfile(name="Vibration Lab", address="Bundesallee 100", email="lab@example.org", country="DE",
                     approvers=(Person("A. Approver", "Head of laboratory"),),
                     standards=(Standard("Reference accelerometer", "RS-1", "PTB-1234", "PTB", "2099-01-01", 0.002),))
    run = RunInfo(certificate_id="VIB-1", customer="ACME", customer_address="1 Main St", customer_email="qa@acme.example",
                  item="accelerometer", manufacturer="ACME", model="A-100", serial="SN-77", calibration_date="2026-03-02",
                  issue_date="2026-03-05", location="laboratory", conditions=(Condition("temperature", 23.1, 0.5, "degC"),))
    return dcc_xml("response", resp, CertificateInfo(lab, run), unit="V/(m/s^2)")


def _tamper_digit(xml: bytes) -> bytes:
    """One digit of the first measured value changed."""
    m = re.search(rb"(<si:value(?:XMLList)?>\s*-?)(\d)", xml)
    d = m.group(2)
    return xml[:m.start(2)] + (b"3" if d != b"3" else b"4") + xml[m.end(2):]


@pytest.mark.parametrize("which", ["lab", "ec"])
def test_signed_dcc_is_schema_valid_and_verifies(dcc, keys, which):
    k, c = keys[which]
    signed = sign_dcc(dcc, k.read_bytes(), c.read_bytes())
    validate_dcc(signed)
    check = verify_dcc(signed, c.read_bytes())
    assert check.signed and check.schema_valid and check.certificate_pinned and f"{which} signer" in check.signer
    assert check.signing_time[:4].isdigit()
    assert verify_dcc(signed).certificate_pinned is False        # integrity with the embedded certificate


def test_tampered_value_signature_or_signer_fail(dcc, keys):
    k, c = keys["lab"]
    signed = sign_dcc(dcc, k.read_bytes(), c.read_bytes())
    with pytest.raises(SignatureInvalid, match="signed value was changed"):
        verify_dcc(_tamper_digit(signed), c.read_bytes())
    sig = re.search(rb"<ds:SignatureValue[^>]*>\s*([^<\s]{20})", signed)
    flipped = sig.group(1)[:10] + (b"A" if sig.group(1)[10:11] != b"A" else b"B") + sig.group(1)[11:]
    with pytest.raises(SignatureInvalid, match="signature"):
        verify_dcc(signed.replace(sig.group(1), flipped), c.read_bytes())
    with pytest.raises(SignatureInvalid, match="signature"):
        verify_dcc(signed, keys["other"][1].read_bytes())         # signed by someone else than the pinned signer
    with pytest.raises(SignatureInvalid, match="no signature"):
        verify_dcc(dcc)
    with pytest.raises(SignatureInvalid, match="schema"):         # valid XML, no longer a DCC
        verify_dcc(signed.replace(b"<dcc:administrativeData>", b"<dcc:administrativeData><dcc:bogus/>", 1))


def test_signing_refuses_bad_material(dcc, keys, tmp_path):
    k, c = keys["lab"]
    with pytest.raises(InputError, match="not the private key"):
        sign_dcc(dcc, k.read_bytes(), keys["other"][1].read_bytes())
    with pytest.raises(InputError, match="not a PEM private key"):
        sign_dcc(dcc, b"garbage", c.read_bytes())
    with pytest.raises(InputError, match="not a PEM X.509"):
        sign_dcc(dcc, k.read_bytes(), b"garbage")
    old_k, old_c = _keypair(tmp_path, "old", days=-1)
    with pytest.raises(InputError, match="renew"):
        sign_dcc(dcc, old_k.read_bytes(), old_c.read_bytes())
    signed = sign_dcc(dcc, k.read_bytes(), c.read_bytes())
    with pytest.raises(InputError, match="already"):
        sign_dcc(signed, k.read_bytes(), c.read_bytes())


# --------------------------------------------------------------------------------------------------------------
# command line: response --dcc --sign-key --sign-cert, then senscal dcc verify



def _response(files, lab):
    return ["response", *files, "--output", "output", "--input-amplitude", "100", "--angle", "angle",
            "--static-sensitivity", "0.05", "--initial-phase-deg", "90", "--u-input", "0.2%",
            "--u-static-sensitivity", "0.05%", "--u-initial-phase-deg", "0.05", "--sensor-id", "SN-1",
            "--calibration-date", "2026-01-05", "--env", "temperature=23.1+-0.5 degC", "--lab", lab]


def test_cli_sign_and_verify(cli, centrifuge_files, keys, tmp_path, lab_profile):
    (tmp_path / "lab.toml").write_text(lab_profile())
    k, c = keys["lab"]
    out = tmp_path / "c.xml"
    r = cli(*_response(centrifuge_files, tmp_path / "lab.toml"), "--dcc", out, "--sign-key", k, "--sign-cert", c,
            "--conformity", "sensitivity=0.05+-5%")
    assert r.code == 0, r.err
    assert "signed and written" in r.err
    r = cli("dcc", "verify", out, "--cert", c)
    assert r.code == 0, r.err
    assert "valid" in r.out and "lab signer" in r.out
    r = cli("dcc", "verify", out, "--json")
    assert r.code == 0 and '"certificate_pinned": false' in r.out
    # one digit changed: exit 3 naming what
    bad = tmp_path / "tampered.xml"
    bad.write_bytes(_tamper_digit(out.read_bytes()))
    r = cli("dcc", "verify", bad, "--cert", c)
    assert r.code == 3 and "signed value was changed" in r.err and len(r.err.strip().splitlines()) == 1, r.err
    r = cli("dcc", "verify", out, "--cert", keys["other"][1])
    assert r.code == 3 and "signature" in r.err
    # an unsigned DCC does not verify
    plain = tmp_path / "plain.xml"
    r = cli(*_response(centrifuge_files, tmp_path / "lab.toml"), "--dcc", plain)
    assert r.code == 0, r.err
    r = cli("dcc", "verify", plain)
    assert r.code == 3 and "no signature" in r.err


@pytest.mark.parametrize("extra, words", [
    (["--sign-key", "KEY"], "go together"),
    (["--sign-key", "KEY", "--sign-cert", "OTHERCERT"], "not the private key"),
    (["--sign-key", "CERT", "--sign-cert", "CERT"], "not a PEM private key"),
    (["--sign-key", "KEY", "--sign-cert", "/nonexistent/c.pem"], "cannot read"),
])
def test_cli_signing_refusals(cli, centrifuge_files, keys, tmp_path, lab_profile, extra, words):
    (tmp_path / "lab.toml").write_text(lab_profile())
    sub = {"KEY": str(keys["lab"][0]), "CERT": str(keys["lab"][1]), "OTHERCERT": str(keys["other"][1])}
    r = cli(*_response(centrifuge_files, tmp_path / "lab.toml"), "--dcc", tmp_path / "c.xml",
            *[sub.get(a, a) for a in extra])
    assert r.code == 2 and words in r.err and len(r.err.strip().splitlines()) == 1, r.err
    assert not (tmp_path / "c.xml").exists()


def test_cli_sign_without_dcc_and_bad_verify_input(cli, centrifuge_files, keys, tmp_path, lab_profile):
    (tmp_path / "lab.toml").write_text(lab_profile())
    k, c = keys["lab"]
    r = cli(*_response(centrifuge_files, tmp_path / "lab.toml"), "--sign-key", k, "--sign-cert", c)
    assert r.code == 2 and "add --dcc" in r.err
    (tmp_path / "x.xml").write_text("hello")
    r = cli("dcc", "verify", tmp_path / "x.xml")
    assert r.code == 2 and "not an XML file" in r.err
