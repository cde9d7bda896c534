"""Lens calibration (`omninav calib`, calib/README.md): where the donut ring is and how it looks.

- `ring`: the ring's centre and radii from ordinary frames, without a target; how a profile is
  corrected when the lens was clipped on a few pixels off (`fit_lens`).
- `board`: calibration boards (chessboard, ChArUco) and their corners in donut frames.
- `ocam`: Scaramuzza's omnidirectional model (OCamCalib) fitted to board corners, and the profile
  (`lens.json`) it converts to.
- `report`: the PNG a calibration writes.
- `commands`: the CLI group; `cli_ring` and `cli_lens` its commands.
"""
