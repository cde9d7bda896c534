"""HTTPS on the LAN from a local certificate authority: phones open the camera only on a secure origin.

A phone trusts the authority once (`ca.pem`, served at /ca.pem; docs/app.md, "On a phone"); the
server's certificate is issued by it for this machine's LAN addresses, and issued anew by the same
authority when the address changes, so the phone keeps trusting it. Caddy's `tls internal` works
the same way.

Notes
-----
The files, in the folder `ensure_cert` is given (`data/tls/`):

- `ca.pem`, `ca-key.pem`: the authority (EC P-256, CA:true, pathlen 0), made once, valid 10 years.
- `cert.pem`, `key.pem`: the server certificate followed by the authority's (the chain nginx
  sends), valid 397 days: Apple refuses server certificates valid longer.

The keys are written 0600 and every file is replaced whole (written beside, then renamed), so a
server never reads half a file.
"""

from __future__ import annotations

import datetime as dt
import ipaddress
import os
import socket
from pathlib import Path

from cryptography import x509
from cryptography.exceptions import InvalidSignature
from cryptography.hazmat.primitives import hashes, serialization
from cryptography.hazmat.primitives.asymmetric import ec
from cryptography.x509.oid import ExtendedKeyUsageOID, NameOID

from ..errors import OmninavError

CA_CERT, CA_KEY = "ca.pem", "ca-key.pem"
CERT, KEY = "cert.pem", "key.pem"
CA_DAYS = 3650
LEAF_DAYS = 397  # Apple refuses server certificates valid longer than 398 days
RENEW_BEFORE = dt.timedelta(days=7)
BACKDATE = dt.timedelta(hours=1)  # a phone whose clock is a little behind still accepts a fresh certificate

Key = ec.EllipticCurvePrivateKey


def lan_addresses() -> list[str]:
    """This machine's LAN address (the one a default route uses), and loopback."""
    out = ["127.0.0.1"]
    try:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            s.connect(("192.0.2.1", 9))  # a documentation address: nothing is sent
            ip = s.getsockname()[0]
            if ip not in out:
                out.append(ip)
    except OSError:
        pass
    return out


def ensure_cert(d: Path, hosts: list[str] | None = None) -> tuple[Path, Path, bool]:
    """-> (chain, key, made): the server certificate in `d` (followed by the authority's) and its
    key, issued now (made) when the one there does not name every host, expires within 7 days or
    was not issued by the authority in `d`. The authority is made first when `d` has none.

    `hosts` defaults to this machine's LAN addresses; localhost and 127.0.0.1 are always named.
    """
    ca, ca_key = _ensure_ca(d)
    cert_p, key_p = d / CERT, d / KEY
    want = wanted_hosts(hosts or lan_addresses())
    now = dt.datetime.now(dt.UTC)
    have = _load_leaf(cert_p, key_p)
    if have is not None and leaf_fits(have[0], have[1], ca, want, now):
        return cert_p, key_p, False
    leaf, key = issue_leaf(ca, ca_key, want, now)
    _write(key_p, _key_pem(key), private=True)
    _write(cert_p, leaf.public_bytes(serialization.Encoding.PEM) + ca.public_bytes(serialization.Encoding.PEM))
    return cert_p, key_p, True


def ca_cert(d: Path) -> Path:
    """The local authority's certificate in `d` (what a phone trusts), made once when there is none."""
    _ensure_ca(d)
    return d / CA_CERT


def ca_fingerprint(d: Path) -> str:
    """The SHA-256 fingerprint of the authority's certificate in `d`, as a phone shows it (AB:CD:...)."""
    return fingerprint(x509.load_pem_x509_certificate(ca_cert(d).read_bytes()))


def fingerprint(cert: x509.Certificate) -> str:
    """A certificate's SHA-256 fingerprint: its DER hashed, in colon-separated upper-case hex."""
    return cert.fingerprint(hashes.SHA256()).hex(":").upper()


def wanted_hosts(hosts: list[str]) -> set[str]:
    """The names a server certificate must carry: the given hosts, localhost and 127.0.0.1 (IP
    addresses written as `san_hosts` reads them back, e.g. IPv6 compressed)."""
    return {str(ipaddress.ip_address(h)) if _is_ip(h) else h for h in hosts} | {"localhost", "127.0.0.1"}


def san_hosts(cert: x509.Certificate) -> set[str]:
    """The DNS names and IP addresses a certificate names (empty without a SubjectAlternativeName)."""
    try:
        san = cert.extensions.get_extension_for_class(x509.SubjectAlternativeName).value
    except x509.ExtensionNotFound:
        return set()
    return {str(v) for v in san.get_values_for_type(x509.IPAddress)} | set(san.get_values_for_type(x509.DNSName))


def issued_by(cert: x509.Certificate, ca: x509.Certificate) -> bool:
    """Whether `ca` issued `cert`: its name is the issuer and its key verifies the signature."""
    try:
        cert.verify_directly_issued_by(ca)
    except (ValueError, TypeError, InvalidSignature):
        return False
    return True


def leaf_fits(leaf: x509.Certificate, key: Key, ca: x509.Certificate, want: set[str], now: dt.datetime) -> bool:
    """Whether a server certificate and key can be kept: `ca` issued it, it is not a CA, `key` is
    its key, it names every wanted host and it stays valid past the next 7 days."""
    try:
        is_ca = leaf.extensions.get_extension_for_class(x509.BasicConstraints).value.ca
    except x509.ExtensionNotFound:
        is_ca = True  # a certificate from before the authority (or from elsewhere): replace it
    return (
        not is_ca
        and issued_by(leaf, ca)
        and leaf.public_key() == key.public_key()
        and want <= san_hosts(leaf)
        and leaf.not_valid_before_utc <= now
        and leaf.not_valid_after_utc > now + RENEW_BEFORE
    )


def ca_fits(ca: x509.Certificate, key: Key, now: dt.datetime) -> bool:
    """Whether an authority can be kept: `key` is its key, it is a CA and it stays valid past the
    next 7 days (a server certificate ends no later than its authority does)."""
    try:
        bc = ca.extensions.get_extension_for_class(x509.BasicConstraints).value
    except x509.ExtensionNotFound:
        return False
    return bc.ca and ca.public_key() == key.public_key() and ca.not_valid_after_utc > now + RENEW_BEFORE


def make_ca(hostname: str, now: dt.datetime) -> tuple[x509.Certificate, Key]:
    """A new authority named after this machine: it may sign server certificates only (pathlen 0)."""
    key = ec.generate_private_key(ec.SECP256R1())
    name = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, f"omninav local CA {hostname}"[:64])])
    start = now - BACKDATE
    cert = (
        x509.CertificateBuilder()
        .subject_name(name)
        .issuer_name(name)
        .public_key(key.public_key())
        .serial_number(x509.random_serial_number())
        .not_valid_before(start)
        .not_valid_after(start + dt.timedelta(days=CA_DAYS))
        .add_extension(x509.BasicConstraints(ca=True, path_length=0), critical=True)
        .add_extension(_usage(key_cert_sign=True, crl_sign=True), critical=True)
        .add_extension(x509.SubjectKeyIdentifier.from_public_key(key.public_key()), critical=False)
        .sign(key, hashes.SHA256())
    )
    return cert, key


def issue_leaf(ca: x509.Certificate, ca_key: Key, hosts: set[str], now: dt.datetime) -> tuple[x509.Certificate, Key]:
    """A server certificate for `hosts` (DNS names and IP addresses) signed by the authority, with
    a new key; it ends no later than the authority does."""
    key = ec.generate_private_key(ec.SECP256R1())
    start = now - BACKDATE
    alt: list[x509.GeneralName] = [x509.DNSName(h) for h in sorted(hosts) if not _is_ip(h)]
    alt += [x509.IPAddress(ipaddress.ip_address(h)) for h in sorted(hosts) if _is_ip(h)]
    cert = (
        x509.CertificateBuilder()
        .subject_name(x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, "omninav local server")]))
        .issuer_name(ca.subject)
        .public_key(key.public_key())
        .serial_number(x509.random_serial_number())
        .not_valid_before(start)
        .not_valid_after(min(start + dt.timedelta(days=LEAF_DAYS), ca.not_valid_after_utc))
        .add_extension(x509.BasicConstraints(ca=False, path_length=None), critical=True)
        .add_extension(_usage(digital_signature=True), critical=True)
        .add_extension(x509.ExtendedKeyUsage([ExtendedKeyUsageOID.SERVER_AUTH]), critical=False)
        .add_extension(x509.SubjectAlternativeName(alt), critical=False)
        .add_extension(x509.SubjectKeyIdentifier.from_public_key(key.public_key()), critical=False)
        .add_extension(x509.AuthorityKeyIdentifier.from_issuer_public_key(ca_key.public_key()), critical=False)
        .sign(ca_key, hashes.SHA256())
    )
    return cert, key


def _ensure_ca(d: Path) -> tuple[x509.Certificate, Key]:
    """The authority in `d`, or a new one written there when it has none that can be kept."""
    d.mkdir(parents=True, exist_ok=True)
    cert_p, key_p = d / CA_CERT, d / CA_KEY
    now = dt.datetime.now(dt.UTC)
    try:
        ca = x509.load_pem_x509_certificate(cert_p.read_bytes())
        key = serialization.load_pem_private_key(key_p.read_bytes(), None)
        if isinstance(key, ec.EllipticCurvePrivateKey) and ca_fits(ca, key, now):
            return ca, key
    except FileNotFoundError:
        pass  # none yet: a new one
    except OSError as e:  # there, but not readable by this user: phones trust it, so it is not replaced
        raise OmninavError(
            f"cannot read the local certificate authority in {d} ({e.strerror}); phones trust it: "
            "give this user access to it (or run as the user who made it) rather than make another"
        ) from None
    except (ValueError, TypeError):
        pass  # garbled: a new one, which phones must trust anew
    ca, key = make_ca(socket.gethostname(), now)
    _write(key_p, _key_pem(key), private=True)
    _write(cert_p, ca.public_bytes(serialization.Encoding.PEM))
    return ca, key


def _load_leaf(cert_p: Path, key_p: Path) -> tuple[x509.Certificate, Key] | None:
    """The server certificate (the first of the chain file) and its key, or None when either is
    missing or unreadable."""
    try:
        cert = x509.load_pem_x509_certificate(cert_p.read_bytes())
        key = serialization.load_pem_private_key(key_p.read_bytes(), None)
    except (OSError, ValueError, TypeError):
        return None
    return (cert, key) if isinstance(key, ec.EllipticCurvePrivateKey) else None


def _write(p: Path, data: bytes, private: bool = False) -> None:
    """Replace `p` whole; a private file is created 0600, so the key is never readable by others."""
    tmp = p.with_name(f".{p.name}.tmp")
    tmp.unlink(missing_ok=True)
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600 if private else 0o644)
    with os.fdopen(fd, "wb") as f:
        f.write(data)
    os.replace(tmp, p)


def _key_pem(key: Key) -> bytes:
    return key.private_bytes(
        serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8, serialization.NoEncryption()
    )


def _usage(digital_signature: bool = False, key_cert_sign: bool = False, crl_sign: bool = False) -> x509.KeyUsage:
    return x509.KeyUsage(
        digital_signature=digital_signature,
        content_commitment=False,
        key_encipherment=False,
        data_encipherment=False,
        key_agreement=False,
        key_cert_sign=key_cert_sign,
        crl_sign=crl_sign,
        encipher_only=False,
        decipher_only=False,
    )


def _is_ip(h: str) -> bool:
    try:
        ipaddress.ip_address(h)
        return True
    except ValueError:
        return False
