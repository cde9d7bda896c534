"""What every `omninav` command reads from the click context: the data folder's server settings
(config.py, with the command line's options over them) and its catalogue. Apart from cli.py so
that the command groups of other packages (calib/, server/) read them without importing it."""

from __future__ import annotations

import functools
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar, cast

import click

if TYPE_CHECKING:  # (imported where a command opens it: SQLAlchemy is a third of the CLI's start)
    from .catalog import Catalog

F = TypeVar("F", bound=Callable[..., Any])


def server_conf(ctx: click.Context, **options: Any) -> dict[str, Any]:
    """The settings (config.py), with the command line's options over them."""
    return ctx.obj["load"]({**ctx.obj["overrides"], **options})  # type: ignore[no-any-return]


def catalog_of(ctx: click.Context) -> Catalog:
    """The catalogue the server of this data folder (and its omninav.cfg) uses, opened once."""
    if "catalog" not in ctx.obj:
        from .catalog import Catalog

        ctx.obj["catalog"] = Catalog.open(server_conf(ctx))
    return ctx.obj["catalog"]  # type: ignore[no-any-return]


def renamed_path_option(new: str, old: str, dest: str, help: str) -> Callable[[F], F]:
    """A required file option, with the name it had in the last release kept as a hidden alias.

    The old name works for one release and says the new one on stderr. Not click's `deprecated`:
    with two options filling one variable it warns whichever name is given.
    """

    def deco(f: F) -> F:
        old_dest = f"{dest}_old_name"
        f = click.option(old, old_dest, type=click.Path(path_type=Path), hidden=True)(f)
        f = click.option(new, dest, type=click.Path(path_type=Path), help=f"{help}  [required]")(f)

        @functools.wraps(f)
        def wrapper(*args: Any, **kwargs: Any) -> Any:
            given = kwargs.pop(old_dest)
            if given is not None:
                if kwargs.get(dest) is not None:
                    raise click.UsageError(f"give {new} only ({old} is its old name)")
                click.echo(f"omninav: {old} is now {new}; the old name goes in the next release", err=True)
                kwargs[dest] = given
            if kwargs.get(dest) is None:
                raise click.UsageError(f"Missing option '{new}'.")
            return f(*args, **kwargs)

        return cast(F, wrapper)

    return deco
