"""nginx's configuration as `omninav serve` writes it (server/nginx.py): nginx itself accepts it,
for HTTP and HTTPS, and it says what the settings say. The attacks it holds are in test_front.py."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from omninav.errors import OmninavError
from omninav.server import nginx
from omninav.server.tls import ensure_cert


def front(tmp_path: Path, **kw) -> nginx.Front:
    return nginx.Front(
        str(tmp_path), str(tmp_path / "app.sock"), str(tmp_path / "events.sock"), "127.0.0.1", 8000, **kw
    )


def nginx_accepts(f: nginx.Front) -> None:
    """serve's own check (`nginx -t` on the written file) passes, and the command names that file."""
    cmd = nginx.check(nginx.binary(), f)
    assert cmd[cmd.index("-c") + 1] == str(Path(f.run_dir) / "nginx.conf")


def test_nginx_accepts_the_configuration_for_http_and_https(tmp_path):
    (tmp_path / "a").mkdir()
    nginx_accepts(front(tmp_path / "a"))
    cert, key, _ = ensure_cert(tmp_path / "tls", ["127.0.0.1"])
    (tmp_path / "b").mkdir()
    f = front(tmp_path / "b", cert=str(cert), key=str(key), trust_proxy=True, locate_rate=0.5, timeout_s=1.5)
    nginx_accepts(f)
    text = nginx.config(f)
    assert "listen 127.0.0.1:8000 ssl" in text and f"ssl_certificate {cert};" in text
    assert "real_ip_header X-Forwarded-For;" in text and "real_ip_recursive off;" in text
    assert "client_header_timeout 1500ms;" in text


def test_the_settings_become_nginx_limits(tmp_path):
    text = nginx.config(front(tmp_path, locate_rate=10, locate_burst=30, client_requests=7))
    assert "rate=10r/s" in text and "limit_req zone=locate burst=29 nodelay;" in text  # 30 at once in all
    assert "limit_conn client 7;" in text
    assert "real_ip" not in text  # no proxy trusted: the peer is the client
    # locate is limited by the normalised path (nginx decodes %XX, drops '#...', merges '//')
    assert re.search(r"location ~ \^/api/venues/\[\^/\]\+/locate\$ \{\n\s+limit_req", text)
    off = nginx.config(front(tmp_path, locate_rate=0))
    assert "limit_req" not in off.replace("limit_req_status", "").replace("limit_req_log_level", "")


@pytest.mark.parametrize(
    ("per_s", "want"), [(10, "10r/s"), (1, "1r/s"), (0.5, "30r/m"), (2.5, "150r/m"), (0.001, "1r/m")]
)
def test_rates_in_nginx_units(per_s, want):
    assert nginx.rate(per_s) == want


def test_what_nginx_answers_itself_is_the_api_json(tmp_path):
    text = nginx.config(front(tmp_path, max_body=1000))
    bodies = re.findall(r"return (\d+) '((?:[^'\\]|\\.)*)';", text)
    assert len(bodies) == len(nginx.ERRORS)
    for status, quoted in bodies:
        doc = json.loads(quoted.replace("\\'", "'").replace("\\\\", "\\"))
        assert doc["status"] == int(status) and doc["error"] and "$" not in quoted
    assert "the limit here is 1000 bytes" in text
    assert "error_page 494 =431" in text  # nginx's own 'head too large' is the API's 431
    # an error page takes no body limit of its own: a refused upload is told why, not 413
    assert text.count("client_max_body_size 0;") == len(nginx.ERRORS) + 1  # and the token check's


def test_a_missing_nginx_says_how_to_install_it():
    with pytest.raises(OmninavError, match="apt-get install nginx-light"):
        nginx.binary("/nonexistent/nginx")
