"""Calibration boards: the spec, the rendered calibration videos and their truth, and the corners
`detect_board` finds in them (against the renderer's exact corner pixels).

Renders are made here, seeded, and cached per module: ~25 s in all on one core.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from omninav.calib.board import (
    MAX_SIDE,
    BoardSpec,
    board_image,
    detect_board,
    flip_chess_ids,
    parse_board,
)
from omninav.calib.ring import Ring
from omninav.errors import OmninavError
from omninav.lens import Catadioptric, pixel_to_direction
from omninav.synth import donut_lens
from omninav.synth.calibration import LENS_GEOMETRIES, CalibSet, board_video, save_stills, save_video

CHESS = "chess:9x6:0.03"
CHARUCO = "charuco:7x5:0.04:0.03"


def ring_of(lens: Catadioptric, dx: float = 0.0, dr: float = 0.0) -> Ring:
    cx, cy = lens.center
    return Ring(lens.image_size, (cx + dx, cy), lens.r_inner + dr, lens.r_outer - dr, 1.0)


_SETS: dict[tuple[str, str, int, float], CalibSet] = {}


def rendered(name: str, spec: str, n: int = 12, noise: float = 2.0) -> CalibSet:
    key = (name, spec, n, noise)
    if key not in _SETS:
        _SETS[key] = board_video(LENS_GEOMETRIES[name], parse_board(spec), n_frames=n, noise=noise, seed=7)
    return _SETS[key]


def symmetric_ids(spec: BoardSpec, ids: np.ndarray, k: int) -> np.ndarray:
    """The chessboard labels under symmetry k: 0 as found, 1 columns reversed, 2 rows, 3 both."""
    c, r = spec.corner_grid
    i, j = ids % c, ids // c
    if k & 1:
        i = c - 1 - i
    if k & 2:
        j = r - 1 - j
    out: np.ndarray = j * c + i
    return out


# --- parse_board ------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "text, kind, cols, rows, square, marker, dictionary",
    [
        ("chess:9x6:0.03", "chess", 9, 6, 0.03, None, None),
        (" CHESS:7X10:0.025 ", "chess", 7, 10, 0.025, None, None),
        ("charuco:7x5:0.04:0.03", "charuco", 7, 5, 0.04, 0.03, "DICT_5X5_100"),
        ("charuco:5x4:0.06:0.045:DICT_4X4_50", "charuco", 5, 4, 0.06, 0.045, "DICT_4X4_50"),
        ("charuco:5x4:0.06:0.045:6x6_250", "charuco", 5, 4, 0.06, 0.045, "DICT_6X6_250"),
    ],
)
def test_parse_board_reads_good_specs(
    text: str, kind: str, cols: int, rows: int, square: float, marker: float | None, dictionary: str | None
) -> None:
    assert parse_board(text) == BoardSpec(kind, cols, rows, square, marker, dictionary)


@pytest.mark.parametrize(
    "text, says",
    [
        ("", "unknown board kind"),
        ("checkers:9x6:0.03", "unknown board kind"),
        ("chess:9x6", "takes 3 fields"),
        ("chess:9x6:0.03:0.02", "takes 3 fields"),
        ("chess:9*6:0.03", "two whole numbers"),
        ("chess:2x6:0.03", "must each be 3 to 64"),
        ("chess:9x100:0.03", "must each be 3 to 64"),
        ("chess:7x7:0.03", "no orientation"),
        ("chess:9x6:abc", "is not a number"),
        ("chess:9x6:-0.03", "positive size in metres"),
        ("chess:9x6:nan", "positive size in metres"),
        ("chess:9x6:30", "did you mean 0.03"),
        ("charuco:7x5:0.04", "takes 4 or 5 fields"),
        ("charuco:7x5:0.04:0.05", "must be smaller than the square"),
        ("charuco:7x5:0.04:0.03:DICT_NOPE", "unknown ArUco dictionary"),
        ("charuco:20x20:0.04:0.03:DICT_4X4_50", "need 200 markers"),
    ],
)
def test_parse_board_says_what_is_wrong_and_the_format(text: str, says: str) -> None:
    with pytest.raises(OmninavError) as e:
        parse_board(text)
    msg = str(e.value)
    assert says in msg and "\n" not in msg
    kind = text.split(":")[0].strip().lower()
    if kind == "charuco":
        assert "charuco:7x5:0.04:0.03:DICT_5X5_100" in msg and "defaults to DICT_5X5_100" in msg
    elif kind == "chess":
        assert "chess:9x6:0.03" in msg and "inner corners" in msg
    else:
        assert "chess:9x6:0.03" in msg and "charuco:7x5:0.04:0.03" in msg


def test_object_points_follow_opencv_order() -> None:
    chess = parse_board("chess:9x6:0.03").object_points()
    assert chess.shape == (54, 3) and chess.dtype == np.float64
    np.testing.assert_allclose(chess[0], [0, 0, 0])
    np.testing.assert_allclose(chess[1] - chess[0], [0.03, 0, 0])  # x fastest, along a row
    np.testing.assert_allclose(chess[9] - chess[0], [0, 0.03, 0])
    np.testing.assert_allclose(chess[-1], [0.24, 0.15, 0])
    spec = parse_board(CHARUCO)
    ch = spec.object_points()
    assert ch.shape == (24, 3) and ch.dtype == np.float64 and not ch[:, 2].any()
    board = cv2.aruco.CharucoBoard((7, 5), 0.04, 0.03, cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_5X5_100))
    np.testing.assert_allclose(ch, np.asarray(board.getChessboardCorners()).reshape(-1, 3), atol=1e-7)


@pytest.mark.parametrize("text", [CHESS, "chess:8x5:0.03", CHARUCO])
def test_board_image_puts_corners_where_object_points_say(text: str) -> None:
    """The printable picture is also the renderer's texture: its corners must sit at
    offset + object point * px-per-metre (pixel centres), found there by OpenCV itself."""
    spec = parse_board(text)
    pps = 60
    img, off = board_image(spec, pps)
    expect = off + spec.object_points()[:, :2] * pps / spec.square_m
    if spec.kind == "chess":
        assert img[int(off) - pps + 5, int(off) - pps + 5] == 0  # black top-left square
        ok, c = cv2.findChessboardCornersSB(img, spec.corner_grid)
        assert ok
        found = c.reshape(-1, 2)
        if np.linalg.norm(found[0] - expect[0]) > 5:
            found = found[::-1]  # OpenCV may start from either end
        ids = np.arange(spec.n_corners)
    else:
        det = cv2.aruco.CharucoDetector(spec.charuco_board())
        cc, ci, _, _ = det.detectBoard(img)
        found, ids = cc.reshape(-1, 2), ci.ravel()
        assert len(ids) == spec.n_corners
    np.testing.assert_allclose(found, expect[ids], atol=0.3)


# --- the renderer -----------------------------------------------------------------------------


def test_lens_geometries_are_varied() -> None:
    lenses = list(LENS_GEOMETRIES.values())
    assert len(lenses) >= 4 and donut_lens(1.0) in lenses
    assert {lens.image_size for lens in lenses} >= {(960, 720), (1280, 960), (1920, 1080)}
    assert {lens.ccw for lens in lenses} == {True, False}
    assert {len(lens.elevation_poly) for lens in lenses} >= {3, 5}  # quadratic and quartic
    assert len({lens.forward_deg for lens in lenses}) == len(lenses)
    for lens in lenses:
        w, h = lens.image_size
        assert 5 <= np.hypot(lens.center[0] - w / 2, lens.center[1] - h / 2) <= 80
        lo, hi = lens.elevation(np.array([lens.r_inner, lens.r_outer]))
        assert lo < -20 and hi > 10  # the inner edge looks down, the outer up
        r = np.linspace(lens.r_inner, lens.r_outer, 200)
        assert np.all(np.diff(lens.elevation(r)) > 0)
        assert lens.center[1] - lens.r_outer >= 0 and lens.center[1] + lens.r_outer <= h  # ring not cut


@pytest.mark.parametrize("name", ["donut960", "wide1280"])
def test_truth_is_self_consistent(name: str) -> None:
    """Each corner's true pixel looks, through the lens, exactly along the corner's direction."""
    cs = rendered(name, CHESS)
    lens = cs.lens
    for (rmat, t), truth in zip(cs.poses, cs.truth, strict=True):
        assert float(rmat[:, 2] @ t) < 0  # the printed side faces the lens
        np.testing.assert_allclose(rmat.T @ rmat, np.eye(3), atol=1e-12)
        x = cs.spec.object_points() @ rmat.T + t
        az0 = np.rad2deg(np.arctan2(x[:, 1], x[:, 0]))
        el0 = np.rad2deg(np.arcsin(x[:, 2] / np.linalg.norm(x, axis=1)))
        seen = np.isfinite(truth[:, 0])
        az, el = pixel_to_direction(lens, truth[seen, 0], truth[seen, 1])
        assert np.abs((az - az0[seen] + 180) % 360 - 180).max() < 0.01
        assert np.abs(el - el0[seen]).max() < 0.01
        lo, hi = lens.elevation_range()
        assert np.all((el0[~seen] < lo + 0.01) | (el0[~seen] > hi - 0.01))  # NaN only off the ring


def test_truth_matches_the_picture() -> None:
    """The rendered board's corners are where the truth says: OpenCV finds the chessboard corners
    of a noiseless render (in the raw frame, near the horizon where it is least distorted) there."""
    lens = LENS_GEOMETRIES["hd1920"]
    cs = board_video(lens, parse_board(CHESS), noise=0.0, blur=0.0, directions=[(0.0, 5.0, 0.45)], max_tilt=0.0)
    grey = cv2.cvtColor(cs.frames[0], cv2.COLOR_BGR2GRAY)
    truth = cs.truth[0]
    crit = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 50, 0.001)
    found = cv2.cornerSubPix(grey, truth.astype(np.float32).reshape(-1, 1, 2), (4, 4), (-1, -1), crit)
    assert np.median(np.hypot(*(found.reshape(-1, 2) - truth).T)) < 0.1


def test_protocol_starts_ahead_then_moves_to_the_phones_left() -> None:
    for name in ("donut960", "wide1280"):
        cs = rendered(name, CHESS)
        lens = cs.lens
        az = np.array([d[0] for d in cs.board_dirs])
        el = np.array([d[1] for d in cs.board_dirs])
        dist = np.array([d[2] for d in cs.board_dirs])
        # near the horizon: as near as a whole board fits the ring (wide1280 sees up to +15 only)
        assert np.all(np.abs((az[:3] + 180) % 360 - 180) < 3) and np.all(np.abs(el[:3]) < 12)
        turn = np.unwrap(np.deg2rad(az[2:]))
        assert np.all(np.diff(turn) < 0)  # azimuth decreasing: to the left, counter-clockwise from above
        assert np.rad2deg(turn[0] - turn[-1]) > 270  # on round the ring
        assert dist.min() >= 0.4 and dist.max() <= 1.5
        # in the picture: frame 0's board centre lies at the image angle `forward_deg`
        centre = np.nanmean(cs.truth[0], axis=0)
        phi = np.rad2deg(np.arctan2(centre[1] - lens.center[1], centre[0] - lens.center[0]))
        assert abs((phi - lens.forward_deg + 180) % 360 - 180) < 4


def test_render_saves_as_video_and_stills(tmp_path: Path) -> None:
    cs = board_video(donut_lens(0.5), parse_board(CHESS), n_frames=3, seed=1)
    assert save_video(tmp_path / "calib.mp4", cs) == 3
    cap = cv2.VideoCapture(str(tmp_path / "calib.mp4"))
    ok, f = cap.read()
    cap.release()
    assert ok and f.shape == cs.frames[0].shape
    paths = save_stills(tmp_path / "stills", cs)
    assert len(paths) == 3 and np.array_equal(cv2.imread(str(paths[1])), cs.frames[1])


# --- detect_board -----------------------------------------------------------------------------


@pytest.mark.parametrize(
    "name, spec",
    [
        ("donut960", CHESS),  # ccw, quadratic, 960x720
        ("wide1280", CHESS),  # cw, quartic, 1280x960
        ("small960", CHESS),  # cw, quartic, small ring
        ("donut960", CHARUCO),  # ccw: the markers read in one mirror sense
        ("wide1280", CHARUCO),  # cw: in the other
        ("hd1920", CHARUCO),  # 1920x1080
    ],
)
def test_detects_corners_within_a_fraction_of_a_pixel(name: str, spec: str) -> None:
    cs = rendered(name, spec)
    ring = ring_of(cs.lens)
    errors, labels, found, whole = [], set(), 0, 0
    for i, frame in enumerate(cs.frames):
        det = detect_board(frame, cs.spec, ring, i)
        whole += cs.whole(i)
        if det is None:
            continue
        found += cs.whole(i)
        assert det.frame == i and det.image_points.shape == (len(det.ids), 2)
        np.testing.assert_array_equal(det.object_points, cs.spec.object_points()[det.ids])
        truth = cs.truth[i]
        if cs.spec.kind == "chess":
            assert det.whole and len(det.ids) == cs.spec.n_corners
            k = min(
                range(4),
                key=lambda k: np.nanmedian(np.hypot(*(det.image_points - truth[symmetric_ids(cs.spec, det.ids, k)]).T)),
            )
            labels.add(k)
            truth = truth[symmetric_ids(cs.spec, det.ids, k)]
        else:
            truth = truth[det.ids]  # markers: the labels are exact
        errors.append(np.hypot(*(det.image_points - truth).T))
    err = np.concatenate(errors)
    assert found >= 0.7 * whole
    assert np.median(err) <= 0.3 and err.max() <= 1.0, (np.median(err), err.max())
    if cs.spec.kind == "chess":
        # the documented labels: as through a mirror lens (ccw), else mirrored, the same every frame
        assert labels == ({0} if cs.lens.ccw else {2})
        ids = np.arange(cs.spec.n_corners)
        assert np.array_equal(flip_chess_ids(cs.spec, ids), symmetric_ids(cs.spec, ids, 2))


def test_detection_survives_a_ring_a_few_pixels_off() -> None:
    """The ring a finder measures is not the lens's exact one: corners map back through whatever
    ring made the view, so they stay as accurate."""
    cs = rendered("donut960", CHESS)
    ring = ring_of(cs.lens, dx=3.0, dr=4.0)
    dets = [detect_board(f, cs.spec, ring, i) for i, f in enumerate(cs.frames[:6])]
    errs = []
    for i, det in enumerate(dets):
        assert det is not None
        errs.append(np.hypot(*(det.image_points - cs.truth[i][det.ids]).T))
    assert np.median(np.concatenate(errs)) < 0.1


def test_board_across_the_seam_is_found() -> None:
    """A board at image angle 0, where the unwrapped views begin and end."""
    lens = LENS_GEOMETRIES["donut960"]
    az = (0.0 - lens.forward_deg) * (-1 if lens.ccw else 1)  # image angle 0
    for spec in (CHESS, CHARUCO):
        cs = board_video(lens, parse_board(spec), directions=[(az, 0.0, 0.45)], max_tilt=10.0, seed=3)
        det = detect_board(cs.frames[0], cs.spec, ring_of(lens))
        assert det is not None and (det.whole or len(det.ids) >= 12)  # ChArUco at 960x720: most markers
        assert np.median(np.hypot(*(det.image_points - cs.truth[0][det.ids]).T)) < 0.3
        angle = np.arctan2(det.image_points[:, 1] - lens.center[1], det.image_points[:, 0] - lens.center[0])
        assert angle.min() < -0.05 and angle.max() > 0.05  # corners on both sides of the seam


def test_partial_boards() -> None:
    """Half off the ring: ChArUco gives the corners it sees (not whole); a chessboard, nothing.
    (1920x1080: at 960x720 the ring's outer part has too few pixels radially for the markers.)"""
    lens = LENS_GEOMETRIES["hd1920"]
    _, hi = lens.elevation_range()
    cs = board_video(lens, parse_board(CHARUCO), directions=[(30.0, hi - 2.0, 0.45)], max_tilt=0.0, seed=4)
    assert not cs.whole(0)
    det = detect_board(cs.frames[0], cs.spec, ring_of(lens))
    assert det is not None and not det.whole and 4 <= len(det.ids) < cs.spec.n_corners
    assert np.isfinite(cs.truth[0][det.ids]).all()
    assert np.hypot(*(det.image_points - cs.truth[0][det.ids]).T).max() < 1.0
    cs = board_video(lens, parse_board(CHESS), directions=[(30.0, hi - 2.0, 0.45)], max_tilt=0.0, seed=4)
    assert not cs.whole(0) and detect_board(cs.frames[0], cs.spec, ring_of(lens)) is None


@pytest.mark.parametrize("spec", [CHESS, CHARUCO])
def test_no_board_no_detection(spec: str) -> None:
    lens = LENS_GEOMETRIES["donut960"]
    ring = ring_of(lens)
    w, h = lens.image_size
    room = board_video(lens, parse_board(spec), directions=[(180.0, 0.0, 40.0)], seed=5).frames[0]  # too far to see
    blank = np.zeros((h, w, 3), np.uint8)
    noise = np.random.default_rng(0).integers(0, 256, (h, w), dtype=np.uint8)
    for frame in (room, blank, noise):
        assert detect_board(frame, parse_board(spec), ring) is None


@pytest.mark.parametrize(
    "name, printed, wrong",
    [
        # small960: OpenCV's detectors find the smaller grids inside the print in a quarter of
        # its frames; only the size check (plain paper one step beyond each side) refuses them
        ("small960", CHESS, "chess:8x6:0.03"),
        ("small960", CHESS, "chess:9x5:0.03"),
        ("small960", CHESS, "chess:7x4:0.03"),
        ("donut960", CHESS, "chess:10x6:0.03"),  # one column more than printed: not the paper's edge
        ("donut960", CHARUCO, "charuco:5x7:0.04:0.03"),
        ("donut960", CHARUCO, "charuco:8x5:0.04:0.03"),
        ("donut960", CHARUCO, "charuco:7x5:0.04:0.03:DICT_4X4_50"),
    ],
)
def test_a_spec_that_does_not_match_the_print_finds_nothing(name: str, printed: str, wrong: str) -> None:
    cs = rendered(name, printed)
    spec, ring = parse_board(wrong), ring_of(cs.lens)
    frames = cs.frames if spec.kind == "chess" else cs.frames[:4]
    assert all(detect_board(f, spec, ring, i) is None for i, f in enumerate(frames))


def test_bad_frames_and_rings_are_one_line_errors() -> None:
    spec = parse_board(CHESS)
    ring = ring_of(LENS_GEOMETRIES["donut960"])
    cases = [
        (np.zeros((40, MAX_SIDE + 1), np.uint8), "larger than 8000 px"),
        (np.zeros((20, 30, 3), np.uint8), "too small"),
        (np.zeros((720, 960, 2), np.uint8), "channels"),
        ("frame.png", "needs an image"),
        (np.zeros((0, 0), np.uint8), "needs an image"),
    ]
    for frame, says in cases:
        with pytest.raises(OmninavError, match=says):
            detect_board(frame, spec, ring)  # type: ignore[arg-type]
    frame = np.zeros((720, 960), np.float32)  # float grey is accepted, as uint8
    assert detect_board(frame, spec, ring) is None
    for bad in (
        Ring((960, 720), (480.0, 360.0), 300.0, 200.0, 1.0),
        Ring((960, 720), (float("nan"), 360.0), 100.0, 200.0, 1.0),
        Ring((960, 720), (5000.0, 360.0), 100.0, 200.0, 1.0),
    ):
        with pytest.raises(OmninavError, match="ring"):
            detect_board(np.zeros((720, 960), np.uint8), spec, bad)
