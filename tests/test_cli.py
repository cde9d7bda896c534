"""The `omninav` console script as a user runs it: real files, real video decoding, subprocesses."""

import json
import shutil

import click
import cv2
import numpy as np
import pytest

from conftest import cli_model, run_cli
from omninav.walk_path import load_walk_path


@pytest.fixture(scope="module")
def cli_venue(small_ds, tmp_path_factory):
    """A venue created and modelled through the CLI itself."""
    data = tmp_path_factory.mktemp("cli-data")
    places = data.parent / f"{data.name}-places.json"  # beside the data folder: small_ds is shared
    places.write_text(json.dumps(small_ds.scene.places))
    p = run_cli(
        "venue",
        "create",
        "lab",
        "--name",
        "Lab",
        "--floor",
        "2",
        "--floorplan",
        str(small_ds.floorplan),
        "--px-per-m",
        "20",
        "--places",
        str(places),
        data=data,
        check=True,
    )
    doc = json.loads(p.stdout)  # the venue's document, as GET /api/venues/lab shows it
    assert doc["id"] == "lab" and doc["name"] == "Lab" and not doc["modelled"]
    [floor] = doc["floors"]
    plan = cv2.imread(str(small_ds.floorplan))
    assert floor["id"] == "2" and floor["px_per_m"] == 20 and floor["plan_size_px"] == [plan.shape[1], plan.shape[0]]
    assert {p["name"] for p in doc["places"]} == {p["name"] for p in small_ds.scene.places}
    p = cli_model(small_ds, "lab", data)
    out = json.loads(p.stdout)
    assert out["frames_added"] > 100 and out["x_realtime"] > 1
    return data


@pytest.fixture(scope="module")
def clips(small_ds, tmp_path_factory):
    """Two 1 s query clips cut from the query walk: one as a video, one as a directory of frames."""
    d = tmp_path_factory.mktemp("clips")
    cap = cv2.VideoCapture(str(small_ds.query_video))
    frames = []
    while True:
        ok, f = cap.read()
        if not ok:
            break
        frames.append(f)
    tr = load_walk_path(small_ds.query_walk_path)
    truth = {}
    a, b = 40, 120  # clips end at frames a+9 and b+9
    vw = cv2.VideoWriter(str(d / "q1.avi"), cv2.VideoWriter_fourcc(*"MJPG"), 10, (480, 360))
    for f in frames[a : a + 10]:
        vw.write(f)
    vw.release()
    (d / "q2").mkdir()
    for i, f in enumerate(frames[b : b + 10]):
        cv2.imwrite(str(d / "q2" / f"{i:03d}.png"), f)
    for name, last in (("q1.avi", a + 9), ("q2", b + 9)):
        xy, hd, _ = tr.pose_at(np.array([last / tr.fps]))
        truth[name] = (xy[0], hd[0])
    return d, truth


def test_locate_prints_one_conventions_answer_per_clip(cli_venue, clips, small_ds):
    d, truth = clips
    p = run_cli(
        "locate", "lab", str(d / "q1.avi"), str(d / "q2"), "--lens", str(small_ds.lens), data=cli_venue, check=True
    )
    lines = p.stdout.strip().splitlines()
    assert len(lines) == 2
    for line in lines:
        a = json.loads(line)
        assert set(a) == {"clip", "x", "y", "heading_deg", "confidence", "floor", "place", "frame"}
        (tx, ty), th = truth[a["clip"]]
        assert np.hypot(a["x"] - tx, a["y"] - ty) < 2.0
        assert abs((a["heading_deg"] - th + 180) % 360 - 180) < 10
        assert 0 <= a["confidence"] <= 1 and 0 <= a["heading_deg"] < 360
        assert a["floor"] == "2" and a["place"].startswith("Corridor")


def test_locate_median_baseline_runs(cli_venue, clips, small_ds):
    d, _ = clips
    p = run_cli("locate", "lab", str(d / "q2"), "--aggregate", "median", data=cli_venue, check=True)
    assert json.loads(p.stdout)["clip"] == "q2"


def evaluate_args(ds, plot):
    """`omninav evaluate` on the venue's query walk, with its walk path and lens, plot to `plot`."""
    return [
        "evaluate",
        "lab",
        str(ds.query_video),
        "--walk-path",
        str(ds.query_walk_path),
        "--lens",
        str(ds.lens),
        "--plot",
        str(plot),
    ]


def test_a_verified_venue_is_made_and_asked_as_any_other(clips, small_ds, tmp_path):
    """The `verified` venue option from the command line: created with its preset, modelled (its
    local features stored beside the frames), asked with clips that are frames."""
    d, truth = clips
    data = tmp_path / "data"
    run_cli("venue", "create", "ver", "--preset", "verified", data=data, check=True)
    out = json.loads(cli_model(small_ds, "ver", data).stdout)
    assert out["frames_added"] > 100
    gen = next((data / "venues" / "ver").glob("gen-*"))
    assert json.loads((gen / "settings.json").read_text())["local_features"] == 900
    assert np.load(gen / "local_descriptors.npy").shape[1] == 32
    # a phone's record for this venue carries the clip's last frame's local features (version 2)
    rec = tmp_path / "q1.onv"
    run_cli("features", "ver", str(d / "q1.avi"), "--lens", str(small_ds.lens), "-o", str(rec), data=data, check=True)
    assert rec.read_bytes()[3] == 2 and rec.stat().st_size > 9000 + 20000
    clips = [str(d / "q1.avi"), str(d / "q2"), str(rec)]
    p = run_cli("locate", "ver", *clips, "--lens", str(small_ds.lens), data=data, check=True)
    answers = [json.loads(line) for line in p.stdout.strip().splitlines()]
    assert [a["clip"] for a in answers] == ["q1.avi", "q2", "q1.onv"]
    for a in answers:
        (tx, ty), _ = truth[a["clip"].replace(".onv", ".avi")]
        assert np.hypot(a["x"] - tx, a["y"] - ty) < 2.0


def test_evaluate_reports_and_plots(cli_venue, small_ds, tmp_path):
    png = tmp_path / "fig.png"
    p = run_cli(
        *evaluate_args(small_ds, png),
        "--json",
        data=cli_venue,
        check=True,
    )
    s = json.loads(p.stdout)
    assert s["clips"] > 20 and s["within_2m"] >= 0.85
    img = cv2.imread(str(png))
    assert img is not None and img.shape[1] > 500


def test_evaluate_takes_longer_clips(cli_venue, small_ds, tmp_path):
    """--clip-s 3: a third as many clips, each answered from 3 s (the app's "keep turning"); a
    length the engine does not take is a usage error, not a traceback."""
    one = json.loads(run_cli(*evaluate_args(small_ds, tmp_path / "a.png"), "--json", data=cli_venue, check=True).stdout)
    p = run_cli(*evaluate_args(small_ds, tmp_path / "b.png"), "--json", "--clip-s", "3", data=cli_venue, check=True)
    three = json.loads(p.stdout)
    assert three["clips"] == one["clips"] // 3
    assert three["within_2m"] >= 0.85
    for bad in ("0.2", "5.5", "x"):
        p = run_cli(*evaluate_args(small_ds, tmp_path / "c.png"), "--clip-s", bad, data=cli_venue)
        assert p.returncode == 2 and "--clip-s" in p.stderr and "Traceback" not in p.stderr


def test_venue_list(cli_venue):
    p = run_cli("venue", "list", data=cli_venue, check=True)
    assert json.loads(p.stdout.splitlines()[0])["id"] == "lab"


def _bad_inputs(small_ds, tmp):
    bad_walk_path = tmp / "bad_walk_path.json"
    bad_walk_path.write_text(
        json.dumps({"fps": 10, "waypoints": [{"frame": 9, "x": 0, "y": 0}, {"frame": 3, "x": 1, "y": 0}]})
    )
    bad_lens = tmp / "bad_lens.json"
    d = json.loads(small_ds.lens.read_text())
    del d["r_outer"]
    bad_lens.write_text(json.dumps(d))
    junk = tmp / "junk.mp4"
    junk.write_bytes(b"\x00" * 5000)
    empty = tmp / "empty"
    empty.mkdir(exist_ok=True)
    m = ["model", "lab", str(small_ds.model_video)]
    t, l = ["--walk-path", str(small_ds.model_walk_path)], ["--lens", str(small_ds.root / "model_lens.json")]
    return [
        (["model", "lab", str(tmp / "nope.mp4"), *t, *l], "video not found"),
        (["model", "lab", str(junk), *t, *l], "not a readable video"),
        ([*m, "--walk-path", str(bad_walk_path), *l], "increasing time"),
        ([*m, *t, "--lens", str(bad_lens)], "r_outer"),
        ([*m, "--walk-path", str(tmp / "none.json"), *l], "walk path file not found"),
        (["model", "nowhere", str(small_ds.model_video), *t, *l], "unknown venue"),
        (["locate", "nowhere", str(junk)], "unknown venue"),
        (["locate", "lab", str(tmp / "nope.mp4")], "clip not found"),
        (["locate", "lab", str(junk)], "not a readable video"),
        (["locate", "lab", str(empty)], "no frame images"),
        (["locate", "lab", str(small_ds.query_video), "--lens", str(tmp / "nolens.json")], "not found"),
        (["venue", "create", "../etc"], "invalid venue id"),
        (["venue", "create", "lab"], "already exists"),
    ]


def test_bad_input_exits_nonzero_with_one_clear_line(cli_venue, small_ds, tmp_path):
    for args, msg in _bad_inputs(small_ds, tmp_path):
        p = run_cli(*args, data=cli_venue)
        assert p.returncode != 0, args
        err = p.stderr.strip()
        assert "Traceback" not in err, (args, err)
        assert len(err.splitlines()) == 1, (args, err)
        assert msg in err, (args, err)


def test_bad_input_loses_nothing(cli_venue, small_ds, tmp_path):
    """After every failed command the venue still answers with the same frames."""
    data = tmp_path / "d"
    shutil.copytree(cli_venue, data)
    before = run_cli("venue", "list", data=data, check=True).stdout
    for args, _ in _bad_inputs(small_ds, tmp_path):
        run_cli(*args, data=data)
    assert run_cli("venue", "list", data=data, check=True).stdout == before


def test_wrong_lens_size_is_explained(cli_venue, clips, small_ds, tmp_path):
    d, _ = clips
    big = json.loads(small_ds.lens.read_text())
    big["image_size"] = [960, 720]
    p = tmp_path / "big.json"
    p.write_text(json.dumps(big))
    r = run_cli("locate", "lab", str(d / "q2"), "--lens", str(p), data=cli_venue)
    assert r.returncode != 0 and "wrong lens profile" in r.stderr


def test_a_long_clip_is_located_by_its_last_frames(cli_venue, small_ds, tmp_path):
    """A whole walk given as one clip (far more frames than a clip needs) still answers, quickly,
    with the pose at its last frame."""
    p = run_cli("locate", "lab", str(small_ds.query_video), "--lens", str(small_ds.lens), data=cli_venue, check=True)
    a = json.loads(p.stdout)
    tr = load_walk_path(small_ds.query_walk_path)
    assert np.hypot(a["x"] - tr.xy[-1, 0], a["y"] - tr.xy[-1, 1]) < 2.0


@pytest.mark.parametrize("suffix", [".onv", ".json"])
def test_features_then_locate_gives_the_same_answer_as_the_clip(cli_venue, clips, small_ds, tmp_path, suffix):
    """What a phone does (extract features, send them) answers exactly as sending the frames."""
    d, _ = clips
    rec = tmp_path / f"q2{suffix}"
    run_cli("features", "lab", str(d / "q2"), "--lens", str(small_ds.lens), "-o", str(rec), data=cli_venue, check=True)
    if suffix == ".onv":
        assert rec.stat().st_size == 20 + 10 * 896  # 916 bytes for the first frame, 896 for each next
    by_rec = json.loads(run_cli("locate", "lab", str(rec), data=cli_venue, check=True).stdout)
    by_clip = json.loads(
        run_cli("locate", "lab", str(d / "q2"), "--lens", str(small_ds.lens), data=cli_venue, check=True).stdout
    )
    by_rec.pop("clip"), by_clip.pop("clip")
    assert by_rec == by_clip


def test_broken_feature_records_are_refused_clearly(cli_venue, tmp_path):
    bad = tmp_path / "bad.onv"
    bad.write_bytes(b"ONV\x01" + b"\x00" * 40)
    p = run_cli("locate", "lab", str(bad), data=cli_venue)
    assert p.returncode != 0 and "Traceback" not in p.stderr and "feature record" in p.stderr
    js = tmp_path / "bad.json"
    js.write_text('{"version": 1, "mag": [[[NaN]]], "phase": [[[0]]]}')
    p = run_cli("locate", "lab", str(js), data=cli_venue)
    assert p.returncode != 0 and len(p.stderr.strip().splitlines()) == 1


def test_a_plot_path_in_a_missing_folder_is_one_clear_line(cli_venue, small_ds, tmp_path):
    target = tmp_path / "missing-dir" / "fig.png"
    p = run_cli(
        *evaluate_args(small_ds, target),
        data=cli_venue,
    )
    assert p.returncode != 0 and "Traceback" not in p.stderr
    assert len(p.stderr.strip().splitlines()) == 1 and "omninav: error" in p.stderr


def test_record_and_lens_errors_name_the_file_and_the_problem(cli_venue, clips, small_ds):
    """Found by hand: a JSON file that is no record, and a --lens that is no lens profile."""
    d, _ = clips
    p = run_cli("locate", "lab", str(small_ds.model_walk_path), data=cli_venue)
    assert (
        p.returncode != 0 and str(small_ds.model_walk_path) in p.stderr and "not an omninav feature record" in p.stderr
    )
    p = run_cli("features", "lab", str(d / "q2"), "--lens", str(small_ds.floorplan), data=cli_venue)
    assert p.returncode != 0 and "lens profile is not readable JSON" in p.stderr and "give --lens" not in p.stderr


def test_a_venue_made_with_the_cli_is_the_servers_and_back(cli_venue, clips, small_ds, tmp_path):
    """One catalogue: what the CLI made, the server lists, describes and answers for (its floor
    and places); what the admin API makes, the CLI lists."""
    from omninav.server import create_app

    data = tmp_path / "d"
    shutil.copytree(cli_venue, data)
    rec = tmp_path / "q2.onv"
    run_cli(
        "features", "lab", str(clips[0] / "q2"), "--lens", str(small_ds.lens), "-o", str(rec), data=data, check=True
    )
    by_cli = json.loads(run_cli("locate", "lab", str(rec), data=data, check=True).stdout)

    app = create_app({"DATA": str(data), "ADMIN_TOKEN": "t" * 32, "JOB_RUNNER": False, "LOCATE_RATE": 0.0})
    c = app.test_client()
    assert [v["id"] for v in c.get("/api/venues").get_json()["venues"]] == ["lab"]
    doc = c.get("/api/venues/lab").get_json()
    assert doc["modelled"] and doc["frames"] > 100 and doc["floors"][0]["id"] == "2"
    assert len(doc["lenses"]) == 1  # the modelling lens, named by its content
    with c.get("/api/venues/lab/floors/2/plan.png") as r:
        assert r.status_code == 200 and r.data[:4] == b"\x89PNG"
    r = c.post("/api/venues/lab/locate", data=rec.read_bytes(), content_type="application/octet-stream")
    assert r.status_code == 200, r.get_json()
    by_api = r.get_json()
    assert by_api["floor"] == by_cli["floor"] == "2"
    assert (by_api["x"], by_api["y"], by_api["heading_deg"]) == (by_cli["x"], by_cli["y"], by_cli["heading_deg"])

    admin = {"Authorization": "Bearer " + "t" * 32}
    assert c.post("/api/admin/venues", json={"id": "hall", "name": "Hall"}, headers=admin).status_code == 201
    ids = [json.loads(line)["id"] for line in run_cli("venue", "list", data=data, check=True).stdout.splitlines()]
    assert ids == ["hall", "lab"]


def test_model_anew_brings_a_venue_modelled_before_its_preset_improved_up_to_date(small_ds, tmp_path):
    """`omninav model --anew`: a venue modelled from the command line before its preset improved
    (here the default preset without the soft clipping, as an omninav from before it made it) gets
    frames with the preset's settings as they are now, as many as before, and answers; a plain
    `model` keeps the venue's settings. Refused, saying why and changing nothing, where the frames
    of another walk would be lost or the venue's walks were uploaded (the admin page models those)."""
    from omninav.catalog import Catalog
    from omninav.config import load_config
    from omninav.lens import load_lens
    from omninav.model_venue import model_video, remove_video
    from omninav.presets import resolve, settings_id

    data = tmp_path / "data"
    plan = ["--floorplan", str(small_ds.floorplan), "--px-per-m", "20"]
    run_cli("venue", "create", "lab", *plan, data=data, check=True)
    cat = Catalog.open(load_config({"DATA": str(data)}))
    lens = small_ds.root / "model_lens.json"
    walk_path, old = load_walk_path(small_ds.model_walk_path), {**resolve("default"), "soft_clip_sd": None}
    model_video(cat.store, "lab", small_ds.model_video, walk_path, load_lens(lens), settings=old)
    other = tmp_path / "second-walk.mp4"
    shutil.copy(small_ds.model_video, other)
    model_video(cat.store, "lab", other, walk_path, load_lens(lens), settings=old)
    frames, live = cat.store.frame_count("lab"), cat.store.generation("lab")
    now = settings_id(resolve("default"))
    assert settings_id(cat.store.settings("lab")) != now

    anew = [
        "model",
        "lab",
        str(small_ds.model_video),
        "--walk-path",
        str(small_ds.model_walk_path),
        "--lens",
        str(lens),
    ]
    p = run_cli(*anew, "--anew", data=data)
    assert p.returncode != 0 and "would drop the frames of 'second-walk.mp4'" in p.stderr, p.stderr
    assert "Traceback" not in p.stderr and cat.store.generation("lab") == live  # nothing changed

    assert remove_video(cat.store, "lab", "second-walk.mp4") > 0
    run_cli(*anew, data=data, check=True)  # a plain modelling keeps the venue's settings
    assert settings_id(cat.store.settings("lab")) != now
    out = json.loads(run_cli(*anew, "--anew", data=data, check=True).stdout)
    assert settings_id(cat.store.settings("lab")) == now
    assert cat.store.modelled_videos("lab") == [small_ds.model_video.name]
    assert out["venue_frames"] == cat.store.frame_count("lab") == frames // 2
    p = run_cli("locate", "lab", str(small_ds.query_video), "--lens", str(small_ds.lens), data=data, check=True)
    assert len(p.stdout.splitlines()) >= 1 and "x" in json.loads(p.stdout.splitlines()[0])

    cat.lenses.put("lab", "donut", json.loads(lens.read_text()))
    evaluation = tmp_path / "eval-walk.mp4"
    shutil.copy(small_ds.model_video, evaluation)
    cat.videos.add_file("lab", evaluation, "1", "donut", None, role="evaluation")  # not a modelling walk
    run_cli(*anew, "--anew", data=data, check=True)
    cat.videos.add_file("lab", other, "1", "donut", json.loads(small_ds.model_walk_path.read_text()))
    p = run_cli(*anew, "--anew", data=data)
    assert p.returncode != 0 and "has uploaded modelling videos ('second-walk.mp4')" in p.stderr, p.stderr
    assert "/api/admin/venues/lab/jobs" in p.stderr


def test_a_renamed_option_keeps_its_old_name_for_a_release(tmp_path):
    """`--walk-path` was `--track`: the old name still works and says the new one; both at once,
    or neither, is a usage error naming the new one."""
    from click.testing import CliRunner

    from omninav.cli_context import renamed_path_option

    @click.command()
    @renamed_path_option("--walk-path", "--track", "walk_path_file", help="walk_path.json")
    def cmd(walk_path_file):
        click.echo(f"read {walk_path_file.name}")

    run = CliRunner().invoke
    new, old = run(cmd, ["--walk-path", "a.json"]), run(cmd, ["--track", "b.json"])
    assert new.exit_code == 0 and new.stdout == "read a.json\n" and new.stderr == ""
    assert old.exit_code == 0 and old.stdout == "read b.json\n"
    assert "--track is now --walk-path" in old.stderr
    both, neither = run(cmd, ["--walk-path", "a.json", "--track", "b.json"]), run(cmd, [])
    assert both.exit_code == 2 and "give --walk-path only" in both.stderr
    assert neither.exit_code == 2 and "Missing option '--walk-path'" in neither.stderr
    assert "--track" not in run(cmd, ["--help"]).stdout  # hidden: the help shows one name


def test_the_commands_read_their_old_walk_path_flags(cli_venue, small_ds, tmp_path):
    """The real commands under their old flags (`--track`, `--eval-track`, and `--track` beside
    tracking's `--track-mode`): the same checks, one line more on stderr naming the new flag."""
    wp, nope = str(small_ds.model_walk_path), str(tmp_path / "nope.mp4")
    lens = ["--lens", str(small_ds.root / "model_lens.json")]
    runs = [
        (["model", "lab", nope, "--track", wp, *lens], "--track is now --walk-path"),
        (["evaluate", "lab", nope, "--track", wp, *lens, "--track-mode"], "--track is now --walk-path"),
        (
            ["choose-preset", str(small_ds.model_video), "--walk-path", wp, *lens, "--eval", nope, "--eval-track", wp],
            "--eval-track is now --eval-walk-path",
        ),
    ]
    for args, said in runs:
        p = run_cli(*args, data=cli_venue)
        lines = p.stderr.strip().splitlines()
        assert p.returncode != 0 and len(lines) == 2, (args, p.stderr)
        assert said in lines[0] and "not found" in lines[1], (args, p.stderr)
