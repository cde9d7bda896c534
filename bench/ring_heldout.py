"""The ring finder on lenses and pictures it was not tuned on (its constants were chosen on
synth/clipon.py's two geometries): the board renders of synth/calibration.py (four geometries, a
bare hard-edged ring, a board in view) and a fisheye without a dark centre; the truth is the lens.

    python -m bench.ring_heldout
"""

from __future__ import annotations

import numpy as np

from bench.common import machine
from omninav.calib.board import parse_board
from omninav.calib.ring import find_ring_frame
from omninav.synth.calibration import LENS_GEOMETRIES, board_video, fisheye_lens

FISHEYE = fisheye_lens()


def main() -> None:
    print(f"machine: {machine()}")
    for name, lens in {**LENS_GEOMETRIES, "fisheye": FISHEYE}.items():
        for noise in (2.0, 6.0):
            cs = board_video(lens, parse_board("chess:9x6:0.03"), n_frames=8, noise=noise, seed=21)
            centre, r_in, r_out, missed = [], [], [], 0
            for f in cs.frames:
                r = find_ring_frame(f)
                if r is None:
                    missed += 1
                    continue
                centre.append(np.hypot(r.center[0] - lens.center[0], r.center[1] - lens.center[1]))
                r_out.append(abs(r.r_outer - lens.r_outer))
                r_in.append(abs(r.r_inner - lens.r_inner))
            print(
                f"{name:9s} noise {noise:.0f}: centre median {np.median(centre):.3f} max {np.max(centre):.3f} px; "
                f"r_outer median {np.median(r_out):.3f} max {np.max(r_out):.3f}; "
                f"r_inner median {np.median(r_in):.3f} max {np.max(r_in):.3f}; missed {missed}/{len(cs.frames)}",
                flush=True,
            )


if __name__ == "__main__":
    main()
