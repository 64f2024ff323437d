"""Signed Digital Calibration Certificates: an enveloped XAdES-B-B XML signature (signxml), and its check.

The signature (W3C XML Signature with the ETSI XAdES signed properties:
signing time and the signer's certificate digest) sits inside the DCC's
optional ``dcc:comment`` element, the one place of the DCC 3.1.2 schema that
takes foreign XML, so a signed DCC still validates.  Its enveloped-signature
transform signs the whole document but the signature itself: any changed
value, unit, date or name breaks the digest.

Bytes in, bytes or a frozen dataclass out; reading the PEM files is the
caller's (:func:`load_signing_material` takes their bytes).
"""

from __future__ import annotations

import datetime as _dt
from dataclasses import dataclass

from senscal._result import ResultMixin
from senscal.errors import DiagnosticError, InputError

__all__ = ["DS_NS", "SignatureCheck", "SignatureInvalid", "load_signing_material", "sign_dcc", "verify_dcc"]

DS_NS = "http://www.w3.org/2000/09/xmldsig#"
DCC_NS = "https://ptb.de/dcc"


class SignatureInvalid(DiagnosticError):
    """A DCC's signature or schema check failed: the message names what (exit 3 on the command line)."""


@dataclass(frozen=True)
class SignatureCheck(ResultMixin):
    """What :func:`verify_dcc` established."""

    schema_valid: bool
    signed: bool
    signer: str              # subject of the signing certificate (RFC 4514)
    signing_time: str        # XAdES SigningTime, ISO 8601
    certificate_pinned: bool  # the signer's certificate was the one given (else only the embedded one: integrity)
    not_after: str           # end of the signing certificate's validity


def load_signing_material(key_pem: bytes, cert_pem: bytes, *, password: bytes | None = None,
                          key_name: str = "--sign-key", cert_name: str = "--sign-cert"):
    """The private key and certificate of a signer, checked to belong together.

    Raises
    ------
    InputError
        Not a PEM private key or certificate, an encrypted key without its password, a key that is not the
        certificate's, a certificate past its validity.
    """
    from cryptography import x509
    from cryptography.hazmat.primitives import serialization

    try:
        key = serialization.load_pem_private_key(key_pem, password=password)
    except TypeError:
        raise InputError(f"{key_name} is an encrypted key; set SENSCAL_SIGN_KEY_PASSWORD to its password") from None
    except ValueError as exc:
        raise InputError(f"{key_name} is not a PEM private key (or the password is wrong): "
                         f"{str(exc).splitlines()[0]}; give the key file of the signing certificate") from None
    try:
        cert = x509.load_pem_x509_certificate(cert_pem)
    except ValueError:
        raise InputError(f"{cert_name} is not a PEM X.509 certificate; give the signer's certificate "
                         "(-----BEGIN CERTIFICATE-----)") from None
    pub = serialization.PublicFormat.SubjectPublicKeyInfo
    if (key.public_key().public_bytes(serialization.Encoding.DER, pub)
            != cert.public_key().public_bytes(serialization.Encoding.DER, pub)):
        raise InputError(f"{key_name} is not the private key of {cert_name} ({cert.subject.rfc4514_string()}); "
                         "give the matching pair")
    now = _dt.datetime.now(_dt.timezone.utc)
    if not cert.not_valid_before_utc <= now <= cert.not_valid_after_utc:
        raise InputError(f"{cert_name} is valid {cert.not_valid_before_utc:%Y-%m-%d} to "
                         f"{cert.not_valid_after_utc:%Y-%m-%d}, not today; renew the signing certificate")
    return key, cert


def _algorithm(key):
    from cryptography.hazmat.primitives.asymmetric import ec, rsa
    from signxml import SignatureMethod

    if isinstance(key, rsa.RSAPrivateKey):
        return SignatureMethod.RSA_SHA256
    if isinstance(key, ec.EllipticCurvePrivateKey):
        return SignatureMethod.ECDSA_SHA256
    raise InputError("--sign-key: only RSA and EC keys sign a DCC here; give one of those")


def sign_dcc(xml: bytes, key_pem: bytes, cert_pem: bytes, *, password: bytes | None = None) -> bytes:
    """The DCC ``xml`` with an enveloped XAdES-B-B signature in its ``dcc:comment``.

    Raises
    ------
    InputError
        As :func:`load_signing_material`; a DCC that already has a comment or a signature.
    """
    from cryptography.hazmat.primitives import serialization
    from lxml import etree
    from signxml.xades import XAdESSigner

    key, cert = load_signing_material(key_pem, cert_pem, password=password)
    root = etree.fromstring(xml)
    if root.find(f"{{{DCC_NS}}}comment") is not None or root.find(f".//{{{DS_NS}}}Signature") is not None:
        raise InputError("the DCC already has a comment or a signature; sign the DCC senscal wrote, once")
    comment = etree.Element(f"{{{DCC_NS}}}comment")
    etree.SubElement(comment, f"{{{DS_NS}}}Signature", Id="placeholder", nsmap={"ds": DS_NS})
    # dcc:comment follows measurementResults and precedes an optional dcc:document
    doc_el = root.find(f"{{{DCC_NS}}}document")
    if doc_el is None:
        root.append(comment)
    else:
        doc_el.addprevious(comment)
    signer = XAdESSigner(signature_algorithm=_algorithm(key))
    signed = signer.sign(root, key=key, cert=cert.public_bytes(serialization.Encoding.PEM))
    return etree.tostring(signed, xml_declaration=True, encoding="utf-8")


def _what_failed(exc: Exception) -> str:
    name = type(exc).__name__
    if name == "InvalidDigest":
        return ("a signed value was changed after signing (digest mismatch: the certificate's content or the "
                "signed properties differ from what was signed)")
    if name == "InvalidSignature":
        return "the signature value does not verify: the signature was changed or made with another key"
    if name == "InvalidCertificate":
        return f"the signing certificate is not the one given or not trusted ({exc})"
    return f"{name}: {exc}"


def verify_dcc(xml: bytes, cert_pem: bytes | None = None) -> SignatureCheck:
    """Check a DCC against the schema and its signature.

    Parameters
    ----------
    xml : bytes
        The DCC.
    cert_pem : bytes, optional
        The signer's certificate (PEM) to pin: the signature must be by it.  Without it the certificate
        embedded in the signature is used, which proves integrity (nothing changed since signing) but not
        who signed.

    Raises
    ------
    SignatureInvalid
        The schema, the signature or the signer fails; the message names which and why.
    InputError
        ``xml`` is not XML, ``cert_pem`` not a certificate.
    """
    from cryptography import x509
    from lxml import etree
    from signxml.xades import XAdESVerifier

    from senscal.report.dcc import DccError, validate_dcc

    try:
        root = etree.fromstring(xml)
    except etree.XMLSyntaxError as exc:
        raise SignatureInvalid(f"not well-formed XML ({exc}): the file was changed or is not a DCC") from None
    sigs = root.findall(f".//{{{DS_NS}}}Signature")
    if not sigs:
        raise SignatureInvalid("the DCC has no signature; sign it with --sign-key KEY.pem --sign-cert CERT.pem")
    if len(sigs) > 1:
        raise SignatureInvalid(f"the DCC has {len(sigs)} signatures; senscal signs once, so it was changed")
    try:
        validate_dcc(xml)
    except DccError as exc:
        raise SignatureInvalid(f"schema: {exc}") from None
    embedded = sigs[0].findtext(f".//{{{DS_NS}}}X509Certificate")
    if cert_pem is not None:
        try:
            given = x509.load_pem_x509_certificate(cert_pem)
        except ValueError:
            raise InputError("--cert is not a PEM X.509 certificate; give the signer's certificate") from None
        pinned = True
    else:
        if not embedded:
            raise SignatureInvalid("the signature carries no certificate; give the signer's with --cert CERT.pem")
        import base64

        given = x509.load_der_x509_certificate(base64.b64decode("".join(embedded.split())))
        pinned = False
    from cryptography.hazmat.primitives import serialization

    pem = given.public_bytes(serialization.Encoding.PEM)
    try:
        results = XAdESVerifier().verify(xml, x509_cert=pem, expect_references=3)
    except Exception as exc:  # signxml's InvalidInput/InvalidDigest/InvalidSignature/InvalidCertificate
        raise SignatureInvalid(f"signature: {_what_failed(exc)}") from None
    # the first reference must be the whole document (enveloped), not a fragment of it
    if etree.QName(results[0].signed_xml).localname != "digitalCalibrationCertificate":
        raise SignatureInvalid("signature: it does not cover the whole DCC")
    xades = "{http://uri.etsi.org/01903/v1.3.2#}"
    when = ""
    for r in results:
        if r.signed_xml is not None and r.signed_xml.tag == f"{xades}SignedProperties":
            when = (r.signed_xml.findtext(f".//{xades}SigningTime") or "").strip()
    return SignatureCheck(True, True, given.subject.rfc4514_string(), when, pinned,
                          given.not_valid_after_utc.date().isoformat())
