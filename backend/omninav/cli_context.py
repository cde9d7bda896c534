"""What every `omninav` command reads from the click context: the data folder's server settings
(config.py, with the command line's options over them) and its catalogue. Apart from cli.py so
that the command groups of other packages (calib/, server/) read them without importing it."""

from __future__ import annotations

from typing import Any

import click

from .catalog import Catalog


def server_conf(ctx: click.Context, **options: Any) -> dict[str, Any]:
    """The settings (config.py), with the command line's options over them."""
    return ctx.obj["load"]({**ctx.obj["overrides"], **options})  # type: ignore[no-any-return]


def catalog_of(ctx: click.Context) -> Catalog:
    """The catalogue the server of this data folder (and its omninav.cfg) uses, opened once."""
    if "catalog" not in ctx.obj:
        ctx.obj["catalog"] = Catalog.open(server_conf(ctx))
    return ctx.obj["catalog"]  # type: ignore[no-any-return]
