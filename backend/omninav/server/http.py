"""What every endpoint shares: JSON errors (never a traceback), request parsing, the client's address."""

from __future__ import annotations

import json
import logging
import math
from typing import Any

from flask import Flask, current_app, jsonify, request
from werkzeug.exceptions import HTTPException, RequestEntityTooLarge

from ..errors import OmninavError

log = logging.getLogger("omninav.server")


class ApiError(Exception):
    """An answer other than success: status and a message that says what was wrong."""

    def __init__(self, status: int, message: str, **extra: Any):
        super().__init__(message)
        self.status = status
        self.message = message
        self.extra = extra


def error_response(status: int, message: str, **extra: Any) -> Any:
    resp = jsonify({"error": message, "status": status, **extra})
    resp.status_code = status
    return resp


def install_error_handlers(app: Flask) -> None:
    @app.errorhandler(ApiError)
    def _api(e: ApiError) -> Any:
        resp = error_response(e.status, e.message, **e.extra)
        if e.status == 429 and "retry_after_s" in e.extra:
            resp.headers["Retry-After"] = str(max(1, math.ceil(e.extra["retry_after_s"])))
        if e.status == 401:
            resp.headers["WWW-Authenticate"] = 'Bearer realm="omninav admin"'
        return resp

    @app.errorhandler(OmninavError)
    def _engine(e: OmninavError) -> Any:  # the engine's bad-input errors: their message is the answer
        return error_response(400, str(e))

    @app.errorhandler(RequestEntityTooLarge)
    def _too_large(e: RequestEntityTooLarge) -> Any:
        limit = request.max_content_length
        return error_response(413, f"request body too large (the limit here is {limit} bytes)")

    @app.errorhandler(HTTPException)
    def _http(e: HTTPException) -> Any:
        code = e.code or 500
        msg = {404: f"not found: {request.path}", 405: f"method {request.method} not allowed on {request.path}"}
        return error_response(code, msg.get(code, e.description or e.name))

    @app.errorhandler(Exception)
    def _bug(e: Exception) -> Any:  # a bug: logged in full, answered in one line
        log.exception("internal error on %s %s", request.method, request.path)
        return error_response(500, f"internal error ({type(e).__name__}); it has been logged")


def json_body(require_object: bool = True) -> Any:
    """The request's JSON body, or a 400 that says why it is not usable."""
    if not request.is_json:
        raise ApiError(415, f"expected Content-Type application/json, got {request.content_type or 'none'}")
    raw = request.get_data(cache=True)
    try:
        obj = json.loads(raw, parse_constant=_no_nan)
    except (UnicodeDecodeError, json.JSONDecodeError) as e:
        raise ApiError(400, f"request body is not valid JSON ({e})") from None
    if require_object and not isinstance(obj, dict):
        raise ApiError(400, "request body must be a JSON object")
    return obj


def _no_nan(name: str) -> Any:
    raise ApiError(400, f"request body contains {name}, which JSON numbers cannot be")


def client_address() -> str:
    if current_app.config["TRUST_PROXY"]:
        fwd = request.headers.get("X-Forwarded-For", "")
        if fwd:
            return fwd.split(",")[0].strip()
    return request.remote_addr or "?"


def str_field(obj: dict[str, Any], key: str, where: str, required: bool = True, max_len: int = 200) -> str | None:
    v = obj.get(key)
    if v is None:
        if required:
            raise ApiError(400, f"{where}: '{key}' is required")
        return None
    if not isinstance(v, str) or not v.strip() or len(v) > max_len:
        raise ApiError(400, f"{where}: '{key}' must be a non-empty string of at most {max_len} characters")
    return v.strip()
