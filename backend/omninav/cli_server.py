"""`omninav serve`, `admin-token`, `backup` and `restore`: the commands that run or keep the
server, registered on the `omninav` command line (cli.py). Each imports the server only when
run: the other commands start without it."""

from __future__ import annotations

import json
from pathlib import Path

import click

from .cli_context import server_conf
from .errors import OmninavError


@click.command()
@click.option("--host", help="Address to listen on (HOST; default 127.0.0.1, every interface with --https).")
@click.option("--port", type=click.IntRange(1, 65535), help="Port (PORT; default 8000).")
@click.option("--https", is_flag=True, default=None, help="HTTPS on the LAN, certificate from a local CA (HTTPS).")
@click.option("--workers", type=click.IntRange(1, 64), help="Worker processes (WORKERS; default: cores + 1).")
@click.option("--threads", type=click.IntRange(1, 256), help="Threads per worker (THREADS; default 4).")
@click.option(
    "--demo",
    type=click.Choice(["full", "quick", "none"]),
    help="The synthetic demo venue set up on first start (DEMO; default full).",
)
@click.pass_context
def serve(
    ctx: click.Context,
    host: str | None,
    port: int | None,
    https: bool | None,
    workers: int | None,
    threads: int | None,
    demo: str | None,
) -> None:
    """Run the server: the API and the web app (gunicorn, several workers). Each option overrides
    its setting (omninav.cfg, OMNINAV_*; docs/operations.md, "Settings")."""
    from .server.serve import default_workers
    from .server.serve import serve as run

    conf = server_conf(ctx, HOST=host, PORT=port, HTTPS=https, WORKERS=workers, THREADS=threads, DEMO=demo)
    host = conf["HOST"] or ("0.0.0.0" if conf["HTTPS"] else "127.0.0.1")
    workers = conf["WORKERS"] or default_workers()
    run(conf, host, conf["PORT"], conf["HTTPS"], workers, conf["THREADS"], conf["DEMO"], echo=click.echo)


@click.command("admin-token")
@click.option("--reset", is_flag=True, help="Make a new admin token (the old one stops working).")
@click.pass_context
def admin_token(ctx: click.Context, reset: bool) -> None:
    """Make the server's admin token (only its hash is kept, so a lost one is replaced, not shown)."""
    from .catalog.db import Db
    from .config import database_url
    from .server.auth import ensure_token, set_token

    db = Db(database_url(server_conf(ctx)))
    db.migrate()
    token = set_token(db) if reset else ensure_token(db)
    if token is None:
        raise OmninavError("an admin token exists already; 'omninav admin-token --reset' replaces it")
    click.echo(token)


@click.command("backup")
@click.argument("dest", type=click.Path(path_type=Path))
@click.option("--no-videos", is_flag=True, help="Leave the modelling videos out (re-modelling needs them again).")
@click.pass_context
def backup_cmd(ctx: click.Context, dest: Path, no_videos: bool) -> None:
    """Back up the server's catalogue, venues, plans and videos into DEST, a new folder (safe while it serves)."""
    from .server.backup import backup

    click.echo(json.dumps(backup(server_conf(ctx), dest, videos=not no_videos)))


@click.command("restore")
@click.argument("src", type=click.Path(path_type=Path))
@click.option("--force", is_flag=True, help="Replace the venues the target database and data folder already have.")
@click.pass_context
def restore_cmd(ctx: click.Context, src: Path, force: bool) -> None:
    """Restore the backup SRC into this data folder and database (stop the server first)."""
    from .server.backup import restore

    click.echo(json.dumps(restore(server_conf(ctx), src, force=force)))


SERVER_COMMANDS = (serve, admin_token, backup_cmd, restore_cmd)
