"""The admin page at /admin: the build's admin.html, never cached, under its own strict policy (no
inline script or style, no WebAssembly, no camera); without a build, the placeholder."""

from __future__ import annotations

from test_server import make_app


def _get(client, path):  # file responses stream: read and close them
    r = client.get(path)
    r.get_data()
    r.close()
    return r


def test_the_admin_page_is_served_at_admin_with_a_strict_policy(tmp_path):
    dist = tmp_path / "dist"
    dist.mkdir()
    (dist / "index.html").write_text("<!doctype html><title>app</title>")
    (dist / "admin.html").write_text("<!doctype html><title>omninav admin</title>")
    client = make_app(tmp_path, WEB_DIST=str(dist)).test_client()
    for path in ("/admin", "/admin/"):
        r = _get(client, path)
        assert r.status_code == 200 and b"omninav admin" in r.data and r.cache_control.max_age == 0
        csp = r.headers["Content-Security-Policy"]
        assert "script-src 'self';" in csp and "style-src 'self';" in csp
        assert "unsafe" not in csp and "frame-ancestors 'none'" in csp
        assert "camera=()" in r.headers["Permissions-Policy"]
    # the phone app keeps its own policy (opencv.js compiles WebAssembly)
    assert "'wasm-unsafe-eval'" in _get(client, "/").headers["Content-Security-Policy"]


def test_without_a_build_admin_is_the_placeholder(tmp_path):
    client = make_app(tmp_path, WEB_DIST=str(tmp_path / "none")).test_client()
    r = _get(client, "/admin")
    assert r.status_code == 200 and b"npm run build" in r.data
