"""The server's pure parts: the rate limiter, settings, schema migrations."""

from __future__ import annotations

import pytest

from omninav.catalog.db import SCHEMA_VERSION, Db
from omninav.config import from_env
from omninav.errors import OmninavError
from omninav.server.ratelimit import RateLimiter


def test_rate_limiter_allows_a_burst_then_the_rate():
    rl = RateLimiter(rate=2.0, burst=3)
    assert [rl.take("a", now=0.0) for _ in range(3)] == [0, 0, 0]
    assert rl.take("a", now=0.0) == pytest.approx(0.5)
    assert rl.take("b", now=0.0) == 0  # per client
    assert rl.take("a", now=0.5) == 0  # a token came back
    assert RateLimiter(rate=0, burst=1).take("a") == 0  # off


def test_settings_from_the_environment_are_typed_and_checked():
    assert from_env({"OMNINAV_LOCATE_RATE": "2.5", "OMNINAV_JOB_RUNNER": "off"}) == {
        "LOCATE_RATE": 2.5,
        "JOB_RUNNER": False,
    }
    with pytest.raises(OmninavError, match="OMNINAV_MAX_UPLOAD_BYTES='lots'"):
        from_env({"OMNINAV_MAX_UPLOAD_BYTES": "lots"})


def test_migrations_run_once_and_a_newer_database_is_refused(tmp_path):
    db = Db(f"sqlite:///{tmp_path / 'x' / 'o.sqlite'}")
    assert db.version() == 0
    assert db.migrate() == SCHEMA_VERSION and db.migrate() == 0
    assert db.version() == SCHEMA_VERSION
    db.set_meta("schema_version", str(SCHEMA_VERSION + 1))
    with pytest.raises(OmninavError, match="newer than this omninav"):
        db.migrate()


def test_lens_names_made_from_video_names_are_renamed_by_content(tmp_path):
    """Finding 10: an inline lens was named 'video-<video name>' and the public venue document lists
    lens names, so a video's name leaked; schema 2 names such lenses by their content instead."""
    from sqlalchemy import text

    from omninav.catalog.db import MIGRATIONS
    from omninav.catalog.lenses import inline_lens_name

    db = Db(f"sqlite:///{tmp_path / 'o.sqlite'}")
    with db.tx() as c:  # a database as schema 1 left it
        for stmt in MIGRATIONS[0]:
            c.execute(text(stmt))
        c.execute(text("INSERT INTO meta VALUES ('schema_version', '1')"))
        c.execute(text("INSERT INTO venues VALUES ('v', 'V', 'default', 0, 0)"))
        prof = '{"model": "equirectangular", "image_size": [720, 360], "forward_x": 360, "ccw": false}'
        c.execute(text("INSERT INTO lenses VALUES ('v', 'video-secret-plans-mp4', :p)"), {"p": prof})
        c.execute(
            text(
                "INSERT INTO videos (venue, name, floor, lens, track, size, status, created) "
                "VALUES ('v', 'secret-plans.mp4', '1', 'video-secret-plans-mp4', '{}', 1, 'ready', 0)"
            )
        )
    db.migrate()
    import json

    want = inline_lens_name(json.loads(prof))
    assert [r["name"] for r in db.all("SELECT name FROM lenses")] == [want]
    assert db.one("SELECT lens FROM videos")["lens"] == want and "secret" not in want
