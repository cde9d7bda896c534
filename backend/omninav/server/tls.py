"""A self-signed certificate for HTTPS on the LAN: phones open the camera only on a secure origin."""

from __future__ import annotations

import datetime as dt
import ipaddress
import socket
from pathlib import Path

from cryptography import x509
from cryptography.hazmat.primitives import hashes, serialization
from cryptography.hazmat.primitives.asymmetric import ec
from cryptography.x509.oid import NameOID


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
    """-> (cert, key, made): reuse the pair in `d` if it names every host, else make a new one."""
    d.mkdir(parents=True, exist_ok=True)
    cert_p, key_p = d / "cert.pem", d / "key.pem"
    want = set(hosts or lan_addresses()) | {"localhost"}
    if cert_p.is_file() and key_p.is_file():
        cert = x509.load_pem_x509_certificate(cert_p.read_bytes())
        san = cert.extensions.get_extension_for_class(x509.SubjectAlternativeName).value
        have = {str(v) for v in san.get_values_for_type(x509.IPAddress)} | set(san.get_values_for_type(x509.DNSName))
        if want <= have and cert.not_valid_after_utc > dt.datetime.now(dt.UTC) + dt.timedelta(days=7):
            return cert_p, key_p, False
    key = ec.generate_private_key(ec.SECP256R1())
    name = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, "omninav local server")])
    alt: list[x509.GeneralName] = [x509.DNSName(h) for h in sorted(want) if not _is_ip(h)]
    alt += [x509.IPAddress(ipaddress.ip_address(h)) for h in sorted(want) if _is_ip(h)]
    now = dt.datetime.now(dt.UTC)
    cert = (
        x509.CertificateBuilder()
        .subject_name(name)
        .issuer_name(name)
        .public_key(key.public_key())
        .serial_number(x509.random_serial_number())
        .not_valid_before(now - dt.timedelta(minutes=5))
        .not_valid_after(now + dt.timedelta(days=397))  # Apple refuses server certificates valid longer
        .add_extension(x509.SubjectAlternativeName(alt), critical=False)
        .add_extension(x509.BasicConstraints(ca=True, path_length=0), critical=True)
        .add_extension(x509.ExtendedKeyUsage([x509.oid.ExtendedKeyUsageOID.SERVER_AUTH]), critical=False)
        .sign(key, hashes.SHA256())
    )
    key_p.write_bytes(
        key.private_bytes(serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8, serialization.NoEncryption())
    )
    key_p.chmod(0o600)
    cert_p.write_bytes(cert.public_bytes(serialization.Encoding.PEM))
    return cert_p, key_p, True


def _is_ip(h: str) -> bool:
    try:
        ipaddress.ip_address(h)
        return True
    except ValueError:
        return False
