"""`omninav demo` (the accuracy table) and `omninav synth`, end to end through the console script."""

import json
import re

import cv2

from conftest import run_cli, seed_quick_demo
from omninav.lens import load_lens
from omninav.walk_path import load_walk_path


def test_demo_quick_prints_both_methods(tmp_path, quick_demo_render):
    seed_quick_demo(tmp_path, quick_demo_render)  # rendered once a run (conftest), modelled here
    p = run_cli("demo", "--quick", data=tmp_path, check=True)
    rows = {line.split("  ")[0]: line for line in p.stdout.splitlines() if "%" in line}
    assert set(rows) == {"omninav (sequence)", "paper (I curve, median)"}
    within_2m = float(re.findall(r"([\d.]+)%", rows["omninav (sequence)"])[1])
    assert within_2m >= 90.0
    assert list((tmp_path / "demo-src-quick").glob("*.eval.png"))
    # a second run reuses the rendered venue and the modelled frames
    again = run_cli("demo", "--quick", data=tmp_path, check=True)
    assert "rendering" not in again.stderr and again.stdout == p.stdout
    # the quick demo has venues of its own, so a later full demo never answers with them
    ids = {json.loads(line)["id"] for line in run_cli("venue", "list", data=tmp_path, check=True).stdout.splitlines()}
    assert ids == {"demo-quick", "demo-quick-paper"}


def test_synth_writes_a_complete_dataset(tmp_path):
    out = tmp_path / "venue"
    p = run_cli("synth", str(out), "--layout", "small", "--scale", "0.5", "--seed", "7", check=True)
    assert json.loads(p.stdout)["px_per_m"] == 20.0
    lens = load_lens(out / "lens.json")
    assert lens.image_size == (480, 360)
    assert load_walk_path(out / "query_walk_path.json").times[-1] > 10
    cap = cv2.VideoCapture(str(out / "query.mp4"))
    ok, frame = cap.read()
    assert ok and frame.shape == (360, 480, 3)
    assert cv2.imread(str(out / "floorplan.png")) is not None
    assert {p["name"] for p in json.loads((out / "places.json").read_text())} == {"Corridor 1", "Corridor 2"}
