"""`omninav calib ...`: the lens calibration commands, gathered from their stage modules."""

from __future__ import annotations

from pathlib import Path

import click

from ..errors import OmninavError
from .cli_lens import lens_cmd
from .cli_ring import check_cmd, ring_cmd

A4_M = (0.210, 0.297)
MAX_BOARD_PX = 200_000_000  # an A0 sheet at 300 dpi is 140 megapixels


@click.group()
def calib() -> None:
    """Lens calibration: find the donut ring, fit a lens profile to a board video, check a video."""


@calib.command("board")
@click.argument("spec")
@click.option("-o", "--out", type=click.Path(path_type=Path), required=True, help="board.pdf or board.png")
@click.option("--dpi", type=click.IntRange(72, 1200), default=300, show_default=True)
def board_cmd(spec: str, out: Path, dpi: int) -> None:
    """A calibration board to print at its true size (SPEC as for `calib lens`, e.g. chess:9x6:0.03)."""
    from PIL import Image

    from .board import board_image, parse_board

    # the picture the renderer and the tests see, a white margin of one square, at `dpi`
    board = parse_board(spec)
    px = int(round(board.square_m / 0.0254 * dpi))
    sx, sy = board.squares
    if (sx + 2) * (sy + 2) * px * px > MAX_BOARD_PX:
        raise OmninavError(
            f"a {sx}x{sy}-square board of {board.square_m * 100:g} cm squares at {dpi} dpi is over "
            f"{MAX_BOARD_PX // 10**6} megapixels: use a lower --dpi or smaller squares"
        )
    img, _ = board_image(board, px_per_square=px)
    exact = px * 0.0254 / board.square_m  # a whole number of dots per square, the square exact in size
    w_m, h_m = img.shape[1] / exact * 0.0254, img.shape[0] / exact * 0.0254
    Image.fromarray(img).save(out, resolution=exact, dpi=(exact, exact))
    fits = (w_m <= A4_M[0] and h_m <= A4_M[1]) or (w_m <= A4_M[1] and h_m <= A4_M[0])
    paper = "fits A4" if fits else "larger than A4: print on a larger sheet or tile it"
    click.echo(
        f"{out}: {w_m * 100:.1f} x {h_m * 100:.1f} cm with its margin ({paper}). Print at 100 % "
        "(actual size, not 'fit to page'), measure a square with a ruler, glue it flat to stiff card."
    )


calib.add_command(ring_cmd)
calib.add_command(lens_cmd)
calib.add_command(check_cmd)
