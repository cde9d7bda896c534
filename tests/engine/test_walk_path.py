import json

import numpy as np
import pytest

from omninav.errors import OmninavError
from omninav.walk_path import load_walk_path, parse_walk_path


def test_interpolation_and_headings():
    tr = parse_walk_path(
        {
            "fps": 10,
            "waypoints": [{"frame": 0, "x": 0, "y": 10}, {"frame": 50, "x": 10, "y": 10}, {"t": 10.0, "x": 10, "y": 0}],
        }
    )
    xy, hd, ok = tr.pose_at(np.array([0.0, 2.5, 5.0, 7.5, 10.0, 10.5]))
    assert ok.tolist() == [True] * 5 + [False]
    assert np.allclose(xy[:5], [[0, 10], [5, 10], [10, 10], [10, 5], [10, 0]])
    # east (+x) is 90; north (-y, up the plan) is 0; at a waypoint the next leg's heading
    assert np.allclose(hd[:5], [90, 90, 0, 0, 0])


def test_heading_offset():
    tr = parse_walk_path(
        {
            "fps": 30,
            "waypoints": [{"frame": 0, "x": 0, "y": 0}, {"frame": 30, "x": 0, "y": 5}],
            "heading_offset_deg": 90,
        }
    )
    _, hd, _ = tr.pose_at(np.array([0.5]))
    assert hd[0] == pytest.approx(270.0)  # walking south (180) + 90


@pytest.mark.parametrize(
    "d,msg",
    [
        ({"fps": 30, "waypoints": [{"frame": 10, "x": 0, "y": 0}, {"frame": 5, "x": 1, "y": 0}]}, "increasing"),
        ({"fps": 30, "waypoints": [{"frame": 0, "x": 0, "y": 0}]}, "at least two"),
        ({"fps": 30, "waypoints": [{"frame": 0, "x": 0}, {"frame": 5, "x": 1, "y": 0}]}, "missing 'y'"),
        ({"fps": 30, "waypoints": [{"x": 0, "y": 0}, {"frame": 5, "x": 1, "y": 0}]}, "'frame' or 't'"),
        ({"fps": 0, "waypoints": []}, "positive"),
        ({"fps": 30, "waypoints": [{"frame": 0, "x": float("nan"), "y": 0}, {"frame": 5, "x": 1, "y": 0}]}, "finite"),
        ([1, 2], "JSON object"),
    ],
)
def test_bad_walk_paths(d, msg):
    with pytest.raises(OmninavError, match=msg):
        parse_walk_path(d)


def test_load_walk_path_file(tmp_path):
    p = tmp_path / "t.json"
    p.write_text(json.dumps({"fps": 30, "waypoints": [{"frame": 0, "x": 0, "y": 0}, {"frame": 5, "x": 1, "y": 0}]}))
    assert load_walk_path(p).fps == 30
    with pytest.raises(OmninavError, match="not found"):
        load_walk_path(tmp_path / "missing.json")


def test_a_stop_keeps_the_heading_it_arrived_with():
    # walk east, stand still 3 s (the same point tagged twice), then walk south
    tr = parse_walk_path(
        {
            "fps": 10,
            "waypoints": [
                {"t": 0, "x": 0, "y": 0},
                {"t": 5, "x": 5, "y": 0},
                {"t": 8, "x": 5, "y": 0},
                {"t": 12, "x": 5, "y": 4},
            ],
        }
    )
    _, h, ok = tr.pose_at(np.array([1.0, 6.0, 7.9, 9.0]))
    assert ok.all()
    np.testing.assert_allclose(h, [90.0, 90.0, 90.0, 180.0])


def test_a_walk_path_that_starts_standing_faces_its_first_move():
    tr = parse_walk_path({"waypoints": [{"t": 0, "x": 2, "y": 2}, {"t": 2, "x": 2, "y": 2}, {"t": 4, "x": 0, "y": 2}]})
    _, h, _ = tr.pose_at(np.array([1.0, 3.0]))
    np.testing.assert_allclose(h, [270.0, 270.0])
