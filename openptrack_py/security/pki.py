"""A site's certificate authority and its nodes' certificates.

Each site has its own authority (``ca.pem``, with its key ``ca.key`` kept on the machine
that issues certificates); each identity (a node name such as ``tracker`` or
``detector_north``, or ``operator``) gets an EC P-256 key and a certificate whose common
name is the identity, which Zenoh's access control matches. Certificates carry both the
server and the client usage, since every Zenoh peer both listens and connects.

Needs the ``cryptography`` package (the ``[security]`` extra); imported only here.
"""

from __future__ import annotations

import datetime
import functools
import ipaddress
import os
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace

from openptrack_py.config.base import NAME_PATTERN
from openptrack_py.errors import ConfigError

CA_NAME = "ca"
"""File stem of the authority: ``ca.pem`` and ``ca.key``."""
CA_DAYS = 3650
CERT_DAYS = 825
"""Validity of a node certificate: the longest that TLS clients commonly accept."""
DEFAULT_HOSTS = ("localhost", "127.0.0.1")


@dataclass(frozen=True)
class Identity:
    """Where one identity's files are.

    Parameters
    ----------
    folder : Path
        The site's certificate folder.
    name : str
        The identity (the certificates' common name).
    """

    folder: Path
    name: str

    @property
    def certificate(self) -> Path:
        """``<folder>/<name>.pem``."""
        return self.folder / f"{self.name}.pem"

    @property
    def key(self) -> Path:
        """``<folder>/<name>.key``."""
        return self.folder / f"{self.name}.key"

    @property
    def authority(self) -> Path:
        """``<folder>/ca.pem``."""
        return self.folder / f"{CA_NAME}.pem"

    def check(self) -> None:
        """Raise a :class:`ConfigError` naming the first missing file and how to make it."""
        if not self.authority.is_file():
            raise ConfigError(
                f"security.certs: no {self.authority}: copy the site's ca.pem from the "
                "machine that holds ca.key (a new authority, openptrack certs init, is only "
                "for a new site)"
            )
        for path in (self.certificate, self.key):
            if not path.is_file():
                raise ConfigError(
                    f"security.certs: no {path} for identity {self.name!r}: copy it from the "
                    f"machine that holds ca.key, where 'openptrack certs issue FOLDER "
                    f"{self.name}' makes it"
                )


@functools.cache
def _crypto() -> SimpleNamespace:
    """The ``cryptography`` modules, imported on first use (an unsecured site never does)."""
    try:
        from cryptography import x509
        from cryptography.exceptions import InvalidSignature
        from cryptography.hazmat.primitives import hashes, serialization
        from cryptography.hazmat.primitives.asymmetric import ec
        from cryptography.x509.oid import ExtendedKeyUsageOID, NameOID
    except ImportError:
        raise ConfigError(
            "certificates need pip install 'openptrack_py[security]' (the cryptography package)"
        ) from None
    return SimpleNamespace(
        x509=x509,
        hashes=hashes,
        serialization=serialization,
        ec=ec,
        eku=ExtendedKeyUsageOID,
        oid=NameOID,
        InvalidSignature=InvalidSignature,
    )


def _write_private(path: Path, data: bytes) -> None:
    """Write a key readable by its owner only."""
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    os.fchmod(fd, 0o600)  # an existing file keeps its mode through O_CREAT
    with os.fdopen(fd, "wb") as out:
        out.write(data)


def _key_pem(key: object) -> bytes:
    c = _crypto()
    return key.private_bytes(  # type: ignore[attr-defined]
        c.serialization.Encoding.PEM,
        c.serialization.PrivateFormat.PKCS8,
        c.serialization.NoEncryption(),
    )


def _now() -> datetime.datetime:
    return datetime.datetime.now(datetime.timezone.utc)


def create_authority(folder: Path, site: str, *, overwrite: bool = False) -> Path:
    """Make the site's authority in ``folder``; return the path of ``ca.pem``.

    Raises
    ------
    ConfigError
        If an authority is there already and ``overwrite`` is false (a new authority
        invalidates every certificate issued by the old one).
    """
    c = _crypto()
    folder.mkdir(parents=True, exist_ok=True)
    cert_path, key_path = folder / f"{CA_NAME}.pem", folder / f"{CA_NAME}.key"
    if cert_path.exists() and not overwrite:
        raise ConfigError(
            f"{cert_path} exists: a new authority would invalidate every certificate it "
            "issued (--force to replace it)"
        )
    key = c.ec.generate_private_key(c.ec.SECP256R1())
    subject = c.x509.Name(
        [
            c.x509.NameAttribute(c.oid.ORGANIZATION_NAME, "openptrack_py"),
            c.x509.NameAttribute(c.oid.COMMON_NAME, f"openptrack_py site {site}"),
        ]
    )
    now = _now()
    usage = c.x509.KeyUsage(
        digital_signature=True,
        key_cert_sign=True,
        crl_sign=True,
        content_commitment=False,
        key_encipherment=False,
        data_encipherment=False,
        key_agreement=False,
        encipher_only=False,
        decipher_only=False,
    )
    cert = (
        c.x509.CertificateBuilder()
        .subject_name(subject)
        .issuer_name(subject)
        .public_key(key.public_key())
        .serial_number(c.x509.random_serial_number())
        .not_valid_before(now - datetime.timedelta(hours=1))
        .not_valid_after(now + datetime.timedelta(days=CA_DAYS))
        .add_extension(c.x509.BasicConstraints(ca=True, path_length=0), critical=True)
        .add_extension(usage, critical=True)
        .add_extension(
            c.x509.SubjectKeyIdentifier.from_public_key(key.public_key()), critical=False
        )
        .sign(key, c.hashes.SHA256())
    )
    _write_private(key_path, _key_pem(key))
    cert_path.write_bytes(cert.public_bytes(c.serialization.Encoding.PEM))
    return cert_path


def _load_authority(folder: Path) -> tuple[object, object]:
    c = _crypto()
    cert_path, key_path = folder / f"{CA_NAME}.pem", folder / f"{CA_NAME}.key"
    if not key_path.is_file():
        raise ConfigError(
            f"no {key_path}: certificates are issued on the machine that holds the site's "
            f"authority key (for a new site: openptrack certs init {folder})"
        )
    cert = c.x509.load_pem_x509_certificate(cert_path.read_bytes())
    key = c.serialization.load_pem_private_key(key_path.read_bytes(), password=None)
    return cert, key


def _alt_names(hosts: Sequence[str]) -> list[object]:
    c = _crypto()
    names: list[object] = []
    for host in dict.fromkeys(hosts):
        try:
            names.append(c.x509.IPAddress(ipaddress.ip_address(host)))
        except ValueError:
            names.append(c.x509.DNSName(host))
    return names


def issue(
    folder: Path,
    name: str,
    hosts: Sequence[str] = (),
    *,
    days: int = CERT_DAYS,
    overwrite: bool = False,
) -> Identity:
    """Issue ``<name>.pem`` and ``<name>.key`` in ``folder``, signed by its authority.

    Parameters
    ----------
    folder : Path
        The site's certificate folder (holding ``ca.pem`` and ``ca.key``).
    name : str
        The identity: the certificate's common name.
    hosts : sequence of str
        Host names and addresses the certificate also names (besides ``localhost`` and
        ``127.0.0.1``), for peers that check names (``security.verify_names``).
    days : int
        Validity.
    overwrite : bool
        Replace an existing certificate of that name.

    Raises
    ------
    ConfigError
        If the authority is missing or the certificate exists and ``overwrite`` is false.
    """
    if not re.match(NAME_PATTERN, name) or len(name) > 64:
        raise ConfigError(
            f"certificate name {name!r}: must be a node name (letters, digits, '_', '.', '-')"
        )
    c = _crypto()
    identity = Identity(folder, name)
    ca_cert, ca_key = _load_authority(folder)
    if identity.certificate.exists() and not overwrite:
        raise ConfigError(f"{identity.certificate} exists (--force to issue it again)")
    key = c.ec.generate_private_key(c.ec.SECP256R1())
    now = _now()
    cert = (
        c.x509.CertificateBuilder()
        .subject_name(c.x509.Name([c.x509.NameAttribute(c.oid.COMMON_NAME, name)]))
        .issuer_name(ca_cert.subject)  # type: ignore[attr-defined]
        .public_key(key.public_key())
        .serial_number(c.x509.random_serial_number())
        .not_valid_before(now - datetime.timedelta(hours=1))
        .not_valid_after(now + datetime.timedelta(days=days))
        .add_extension(c.x509.BasicConstraints(ca=False, path_length=None), critical=True)
        .add_extension(
            c.x509.SubjectAlternativeName(_alt_names([*DEFAULT_HOSTS, *hosts])), critical=False
        )
        .add_extension(
            c.x509.ExtendedKeyUsage([c.eku.SERVER_AUTH, c.eku.CLIENT_AUTH]), critical=False
        )
        .add_extension(
            c.x509.AuthorityKeyIdentifier.from_issuer_public_key(ca_key.public_key()),  # type: ignore[attr-defined]
            critical=False,
        )
        .sign(ca_key, c.hashes.SHA256())  # type: ignore[arg-type]
    )
    _write_private(identity.key, _key_pem(key))
    identity.certificate.write_bytes(cert.public_bytes(c.serialization.Encoding.PEM))
    return identity


@dataclass(frozen=True)
class CertificateInfo:
    """What ``openptrack certs list`` shows of one certificate."""

    name: str
    issuer: str
    not_after: datetime.datetime
    hosts: tuple[str, ...]
    signed_by_site: bool


def describe(folder: Path) -> list[CertificateInfo]:
    """Every certificate in ``folder`` except the authority's, checked against it."""
    c = _crypto()
    ca_path = folder / f"{CA_NAME}.pem"
    if not ca_path.is_file():
        raise ConfigError(f"no {ca_path}: not a certificate folder (openptrack certs init)")
    authority = c.x509.load_pem_x509_certificate(ca_path.read_bytes())
    out = []
    for path in sorted(folder.glob("*.pem")):
        if path.stem == CA_NAME:
            continue
        cert = c.x509.load_pem_x509_certificate(path.read_bytes())
        try:
            cert.verify_directly_issued_by(authority)
            signed = True
        except (ValueError, TypeError, c.InvalidSignature):  # wrong issuer, key, signature
            signed = False
        try:
            sans = cert.extensions.get_extension_for_class(c.x509.SubjectAlternativeName).value
            hosts = tuple(str(v) for v in sans.get_values_for_type(c.x509.DNSName)) + tuple(
                str(v) for v in sans.get_values_for_type(c.x509.IPAddress)
            )
        except c.x509.ExtensionNotFound:
            hosts = ()
        common = cert.subject.get_attributes_for_oid(c.oid.COMMON_NAME)
        out.append(
            CertificateInfo(
                name=str(common[0].value) if common else path.stem,
                issuer=cert.issuer.rfc4514_string(),
                not_after=cert.not_valid_after_utc,
                hosts=hosts,
                signed_by_site=signed,
            )
        )
    return out
