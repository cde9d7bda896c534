"""The local certificate authority (server/tls.py): made once and kept, so that a phone trusts it
once; the server certificate issued by it anew when the address changes; the chain checked with
`cryptography` and with a real TLS handshake; the authority served at /ca.pem."""

from __future__ import annotations

import datetime as dt
import hashlib
import ipaddress
import re
import socket
import ssl
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from cryptography import x509
from cryptography.hazmat.primitives import hashes, serialization
from cryptography.hazmat.primitives.asymmetric import ec
from cryptography.x509.oid import ExtendedKeyUsageOID, NameOID
from cryptography.x509.verification import PolicyBuilder, Store

from omninav.errors import OmninavError
from omninav.server import create_app
from omninav.server.tls import ca_cert, ca_fingerprint, ensure_cert, issue_leaf, issued_by, san_hosts
from server_helpers import TOKEN, Api

HOSTS = ["192.168.1.20"]


def _chain(d: Path) -> list[x509.Certificate]:
    return x509.load_pem_x509_certificates((d / "cert.pem").read_bytes())


def _ca(d: Path) -> x509.Certificate:
    return x509.load_pem_x509_certificate((d / "ca.pem").read_bytes())


def _ext(cert: x509.Certificate, kind: Any) -> Any:
    return cert.extensions.get_extension_for_class(kind)


def _handshake(d: Path, cafile: Path, hostname: str = "127.0.0.1") -> bytes:
    """Serve `d`'s certificate and key on 127.0.0.1 from a thread, connect trusting only `cafile`
    (strict X.509 checks, as Python 3.13 makes the default) and return what the server sent."""
    server = ssl.SSLContext(ssl.PROTOCOL_TLS_SERVER)
    server.load_cert_chain(d / "cert.pem", d / "key.pem")
    failed: list[BaseException] = []
    with socket.create_server(("127.0.0.1", 0)) as listener:
        listener.settimeout(10)

        def serve() -> None:
            try:
                conn, _ = listener.accept()
                with server.wrap_socket(conn, server_side=True) as tls:
                    tls.sendall(b"hello")
            except (OSError, ssl.SSLError) as e:  # the client refused us: the client side says why
                failed.append(e)

        t = threading.Thread(target=serve)
        t.start()
        try:
            client = ssl.create_default_context(cafile=str(cafile))
            client.verify_flags |= ssl.VERIFY_X509_STRICT
            with socket.create_connection(listener.getsockname(), timeout=10) as raw:
                with client.wrap_socket(raw, server_hostname=hostname) as tls:
                    return tls.recv(5)
        finally:
            t.join(10)


def test_the_authority_is_made_once_and_kept(tmp_path: Path) -> None:
    d = tmp_path / "tls"
    chain, key, made = ensure_cert(d, HOSTS)
    assert (chain, key, made) == (d / "cert.pem", d / "key.pem", True)
    ca_pem, chain_pem = (d / "ca.pem").read_bytes(), chain.read_bytes()
    assert ensure_cert(d, HOSTS) == (chain, key, False)
    assert ca_cert(d) == d / "ca.pem"
    assert (d / "ca.pem").read_bytes() == ca_pem and chain.read_bytes() == chain_pem

    ca = _ca(d)
    assert ca.subject.get_attributes_for_oid(NameOID.COMMON_NAME)[0].value == f"omninav local CA {socket.gethostname()}"
    assert ca.issuer == ca.subject
    bc = _ext(ca, x509.BasicConstraints)
    assert bc.critical and bc.value.ca and bc.value.path_length == 0
    ku = _ext(ca, x509.KeyUsage).value
    assert ku.key_cert_sign and ku.crl_sign and not ku.digital_signature
    pub = ca.public_key()
    assert isinstance(pub, ec.EllipticCurvePublicKey) and isinstance(pub.curve, ec.SECP256R1)
    assert (ca.not_valid_after_utc - ca.not_valid_before_utc).days == 3650


def test_a_new_address_gets_a_certificate_from_the_same_authority(tmp_path: Path) -> None:
    """The authority's file does not change, so a phone that trusted it keeps connecting."""
    d = tmp_path / "tls"
    ensure_cert(d, HOSTS)
    phone = tmp_path / "trusted-by-the-phone.pem"
    phone.write_bytes((d / "ca.pem").read_bytes())
    old_leaf = _chain(d)[0]

    assert ensure_cert(d, ["10.0.0.7"])[2]
    assert (d / "ca.pem").read_bytes() == phone.read_bytes()
    leaf = _chain(d)[0]
    assert leaf.serial_number != old_leaf.serial_number
    assert issued_by(leaf, _ca(d)) and "10.0.0.7" in san_hosts(leaf)
    assert _handshake(d, phone) == b"hello"


def test_the_chain_verifies_against_the_authority(tmp_path: Path) -> None:
    d = tmp_path / "tls"
    ensure_cert(d, [*HOSTS, "omninav.local"])
    ca = _ca(d)
    leaf, second = _chain(d)
    assert second == ca  # the chain nginx sends: the server certificate, then the authority's

    pub = ca.public_key()
    assert isinstance(pub, ec.EllipticCurvePublicKey) and leaf.signature_hash_algorithm is not None
    pub.verify(leaf.signature, leaf.tbs_certificate_bytes, ec.ECDSA(leaf.signature_hash_algorithm))
    assert leaf.issuer == ca.subject
    assert san_hosts(leaf) == {"192.168.1.20", "omninav.local", "localhost", "127.0.0.1"}
    bc = _ext(leaf, x509.BasicConstraints)
    assert bc.critical and not bc.value.ca
    assert _ext(leaf, x509.KeyUsage).value.digital_signature
    assert list(_ext(leaf, x509.ExtendedKeyUsage).value) == [ExtendedKeyUsageOID.SERVER_AUTH]
    assert leaf.not_valid_after_utc - leaf.not_valid_before_utc == dt.timedelta(days=397)
    key = serialization.load_pem_private_key((d / "key.pem").read_bytes(), None)
    assert isinstance(key, ec.EllipticCurvePrivateKey) and key.public_key() == leaf.public_key()

    # as a TLS client does: the path from the server certificate to the trusted authority
    verifier = (
        PolicyBuilder().store(Store([ca])).build_server_verifier(x509.IPAddress(ipaddress.ip_address("192.168.1.20")))
    )
    assert verifier.verify(leaf, [ca])[-1] == ca


@pytest.mark.parametrize("hostname", ["127.0.0.1", "localhost"])
def test_python_ssl_trusting_the_authority_completes_the_handshake(tmp_path: Path, hostname: str) -> None:
    d = tmp_path / "tls"
    ensure_cert(d, HOSTS)
    assert _handshake(d, d / "ca.pem", hostname) == b"hello"


def test_python_ssl_refuses_a_server_of_another_authority(tmp_path: Path) -> None:
    ensure_cert(tmp_path / "ours", HOSTS)
    ensure_cert(tmp_path / "theirs", HOSTS)
    with pytest.raises(ssl.SSLCertVerificationError):
        _handshake(tmp_path / "theirs", tmp_path / "ours" / "ca.pem")


def _another_authority(d: Path) -> None:
    other = d.parent / "other"
    ensure_cert(other, HOSTS)
    for name in ("cert.pem", "key.pem"):
        (d / name).write_bytes((other / name).read_bytes())


def _expiring(d: Path) -> None:
    """A certificate of this authority issued 391 days ago: 6 days left."""
    ca_key = serialization.load_pem_private_key((d / "ca-key.pem").read_bytes(), None)
    assert isinstance(ca_key, ec.EllipticCurvePrivateKey)
    then = dt.datetime.now(dt.UTC) - dt.timedelta(days=391)
    leaf, key = issue_leaf(_ca(d), ca_key, {*HOSTS, "localhost", "127.0.0.1"}, then)
    (d / "cert.pem").write_bytes(leaf.public_bytes(serialization.Encoding.PEM))
    (d / "key.pem").write_bytes(_key_pem(key))


def _wrong_key(d: Path) -> None:
    (d / "key.pem").write_bytes(_key_pem(ec.generate_private_key(ec.SECP256R1())))


def _garbled(d: Path) -> None:
    (d / "cert.pem").write_text("not a certificate")


@pytest.mark.parametrize("spoil", [_another_authority, _expiring, _wrong_key, _garbled])
def test_a_certificate_that_cannot_be_kept_is_issued_anew_by_the_same_authority(
    tmp_path: Path, spoil: Callable[[Path], None]
) -> None:
    d = tmp_path / "tls"
    ensure_cert(d, HOSTS)
    ca_pem = (d / "ca.pem").read_bytes()
    spoil(d)
    assert ensure_cert(d, HOSTS)[2]
    assert (d / "ca.pem").read_bytes() == ca_pem
    assert issued_by(_chain(d)[0], _ca(d))
    assert _handshake(d, d / "ca.pem") == b"hello"
    assert not ensure_cert(d, HOSTS)[2]


def test_an_old_self_signed_certificate_is_replaced(tmp_path: Path) -> None:
    """What --https made before the authority: one self-signed certificate (CA:true), no ca.pem."""
    d = tmp_path / "tls"
    d.mkdir()
    key = ec.generate_private_key(ec.SECP256R1())
    name = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, "omninav local server")])
    now = dt.datetime.now(dt.UTC)
    old = (
        x509.CertificateBuilder()
        .subject_name(name)
        .issuer_name(name)
        .public_key(key.public_key())
        .serial_number(x509.random_serial_number())
        .not_valid_before(now - dt.timedelta(minutes=5))
        .not_valid_after(now + dt.timedelta(days=397))
        .add_extension(
            x509.SubjectAlternativeName([x509.DNSName("localhost"), x509.IPAddress(ipaddress.ip_address("127.0.0.1"))]),
            critical=False,
        )
        .add_extension(x509.BasicConstraints(ca=True, path_length=0), critical=True)
        .sign(key, hashes.SHA256())
    )
    (d / "cert.pem").write_bytes(old.public_bytes(serialization.Encoding.PEM))
    (d / "key.pem").write_bytes(_key_pem(key))
    (d / "key.pem").chmod(0o644)

    assert ensure_cert(d, ["127.0.0.1"])[2]
    leaf = _chain(d)[0]
    assert leaf != old and issued_by(leaf, _ca(d))
    assert (d / "key.pem").stat().st_mode & 0o777 == 0o600


def test_the_keys_are_readable_by_their_owner_only(tmp_path: Path) -> None:
    d = tmp_path / "tls"
    ensure_cert(d, HOSTS)
    ensure_cert(d, ["10.0.0.7"])  # issued anew: still private
    assert sorted(p.name for p in d.iterdir()) == ["ca-key.pem", "ca.pem", "cert.pem", "key.pem"]  # no leftovers
    assert (d / "ca-key.pem").stat().st_mode & 0o777 == 0o600
    assert (d / "key.pem").stat().st_mode & 0o777 == 0o600


def test_the_fingerprint_is_the_sha256_of_the_authority(tmp_path: Path) -> None:
    d = tmp_path / "tls"
    ensure_cert(d, HOSTS)
    fp = ca_fingerprint(d)
    assert re.fullmatch(r"([0-9A-F]{2}:){31}[0-9A-F]{2}", fp)
    der = _ca(d).public_bytes(serialization.Encoding.DER)
    assert fp.replace(":", "").lower() == hashlib.sha256(der).hexdigest()


def test_the_authority_is_served_at_ca_pem(tmp_path: Path) -> None:
    data = tmp_path / "data"
    app = create_app({"DATA": str(data), "ADMIN_TOKEN": TOKEN, "JOB_RUNNER": False})
    api = Api(app.test_client())  # every answer checked against openapi.yaml
    r = api.get("/ca.pem")
    assert r.status_code == 404 and r.is_json and "--https" in r.get_json()["error"]

    ensure_cert(data / "tls", HOSTS)
    r = api.get("/ca.pem", buffered=True)  # read whole: the file is closed
    assert r.status_code == 200 and r.mimetype == "application/x-x509-ca-cert"
    assert r.get_data() == (data / "tls" / "ca.pem").read_bytes()
    assert b"PRIVATE" not in r.get_data()


def _key_pem(key: ec.EllipticCurvePrivateKey) -> bytes:
    return key.private_bytes(
        serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8, serialization.NoEncryption()
    )


def test_an_authority_this_user_cannot_read_is_not_replaced(tmp_path: Path, monkeypatch) -> None:
    """Phones trust the authority: one that is there but unreadable (made by root, say) is an
    error that says so, never silently a new one."""
    ensure_cert(tmp_path, ["127.0.0.1"])
    before = (tmp_path / "ca.pem").read_bytes()
    real = Path.read_bytes

    def denied(self: Path) -> bytes:
        if self.name == "ca-key.pem":
            raise PermissionError(13, "Permission denied", str(self))
        return real(self)

    monkeypatch.setattr(Path, "read_bytes", denied)
    with pytest.raises(OmninavError, match="cannot read the local certificate authority"):
        ensure_cert(tmp_path, ["127.0.0.1", "10.0.0.9"])
    monkeypatch.undo()
    assert (tmp_path / "ca.pem").read_bytes() == before
