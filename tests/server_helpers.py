"""Helpers for the server tests: an API client that checks every response against openapi.yaml,
and query clips of the small synthetic venue with their true poses."""

from __future__ import annotations

import json
import re
from typing import Any

import numpy as np
from jsonschema import Draft202012Validator
from referencing import Registry, Resource
from referencing.jsonschema import DRAFT202012

from omninav.calib.correct import clip_spectra as clip_lens_spectra
from omninav.extract import Extractor
from omninav.lens import load_lens
from omninav.server.venues_api import openapi_doc
from omninav.video import VideoInfo, iter_video
from omninav.walk_path import load_walk_path

TOKEN = "test-admin-token"
ADMIN = {"Authorization": f"Bearer {TOKEN}"}
SPEC = openapi_doc()
_REG = Registry().with_resource("urn:omninav", Resource.from_contents(SPEC, default_specification=DRAFT202012))


def _pointer(*parts: str) -> str:
    return "/".join(p.replace("~", "~0").replace("/", "~1") for p in parts)


def spec_path(path: str) -> str | None:
    """A concrete request path -> its template in the spec."""
    for tmpl in SPEC["paths"]:
        rx = "^" + re.sub(r"\\\{[^}]+\\\}", r"[^/]+", re.escape(tmpl)) + "$"
        if re.match(rx, path):
            return tmpl
    return None


def check_response(method: str, path: str, status: int, content_type: str, body: bytes) -> None:
    """The response must be one the spec documents, and a JSON body must match its schema."""
    tmpl = spec_path(path.split("?")[0])
    assert tmpl is not None, f"{path} is not in openapi.yaml"
    op = SPEC["paths"][tmpl].get(method.lower())
    assert op is not None, f"{method} {tmpl} is not in openapi.yaml"
    key = str(status) if str(status) in op["responses"] else f"{status // 100}XX"
    assert key in op["responses"], f"{method} {tmpl}: status {status} is not documented"
    resp = op["responses"][key]
    if "$ref" in resp:
        resp = SPEC["components"]["responses"][resp["$ref"].rsplit("/", 1)[1]]
        ptr = _pointer("components", "responses", "Error", "content", "application/json", "schema")
    else:
        ptr = _pointer("paths", tmpl, method.lower(), "responses", key, "content", "application/json", "schema")
    ctype = content_type.split(";")[0]
    if status == 204:
        return
    assert ctype in resp.get("content", {}), f"{method} {tmpl} {status}: {ctype} not documented"
    if ctype == "application/json":
        v = Draft202012Validator({"$ref": f"urn:omninav#/{ptr}"}, registry=_REG)
        errors = sorted(v.iter_errors(json.loads(body)), key=lambda e: e.path)
        assert not errors, f"{method} {path} {status}: {errors[0].message} at {list(errors[0].path)}"


class Api:
    """The Flask test client, every response checked against the spec."""

    def __init__(self, client: Any):
        self.c = client

    def __getattr__(self, method: str) -> Any:
        def call(path: str, **kw: Any) -> Any:
            r = getattr(self.c, method)(path, **kw)
            if r.mimetype != "text/event-stream":
                verb = kw.get("method", "GET") if method == "open" else method
                check_response(verb.upper(), path, r.status_code, r.content_type or "", r.get_data())
            return r

        return call


def query_clip(ds: Any, start: int, n: int = 10) -> tuple[list[np.ndarray], tuple[float, float, float]]:
    """n frames of the query walk from `start`, and the true (x, y, heading) at the last one."""
    info = VideoInfo(ds.query_video)
    frames = []
    for i, f in iter_video(info, start=start):
        if i >= start + n:
            break
        frames.append(f)
    tr = load_walk_path(ds.query_walk_path)
    xy, h, _ = tr.pose_at(np.array([(start + n - 1) / tr.fps]))
    return frames, (float(xy[0, 0]), float(xy[0, 1]), float(h[0]))


def clip_spectra(ds: Any, frames: list[np.ndarray], conf: dict) -> np.ndarray:
    """The feature record a phone makes of these frames: through the lens corrected for where its
    ring sits in them, as the phone's worker (and every engine path) does."""
    return clip_lens_spectra(load_lens(ds.lens), frames, lambda lz: Extractor(lz, conf).spectrum)[0]


def heading_error(a: float, b: float) -> float:
    return abs((a - b + 180.0) % 360.0 - 180.0)


def far_and_truth(loc: Any, tx: float, ty: float) -> tuple[int, int]:
    """The venue rows farthest from and nearest to (tx, ty)."""
    d = np.hypot(loc.xy[:, 0] - tx, loc.xy[:, 1] - ty)
    return int(np.argmax(d)), int(np.argmin(d))
