"""What every endpoint shares: JSON errors (never a traceback), request parsing, the client's address."""

from __future__ import annotations

import json
import logging
import math
from typing import Any

from flask import Flask, current_app, jsonify, request
from werkzeug.exceptions import HTTPException, RequestEntityTooLarge

from ..errors import Busy, Conflict, NoRoom, NotFound, OmninavError, OutOfRange, Stale, TooLarge, Unusable

log = logging.getLogger("omninav.server")

# The app's own origin only; opencv.js compiles its WebAssembly ('wasm-unsafe-eval'); no inline
# script or style; the annotated plan arrives as a data: URL; no framing.
CSP = (
    "default-src 'self'; script-src 'self' 'wasm-unsafe-eval'; worker-src 'self'; connect-src 'self'; "
    "img-src 'self' data: blob:; media-src 'self' blob:; style-src 'self'; object-src 'none'; "
    "base-uri 'none'; form-action 'self'; frame-ancestors 'none'"
)
# The feature worker alone may also evaluate strings: opencv.js's embind builds its function
# wrappers with Function() (measured: without 'unsafe-eval' the worker never starts). A worker's
# policy comes with its own script, and the worker has no DOM, so the page keeps the strict one.
WORKER_CSP = "default-src 'self'; script-src 'self' 'wasm-unsafe-eval' 'unsafe-eval'; connect-src 'self'"


# What each kind of user error (errors.py) is in HTTP; any other OmninavError is a 400.
STATUS: dict[type[OmninavError], int] = {
    NotFound: 404,
    Conflict: 409,
    Stale: 412,
    TooLarge: 413,
    OutOfRange: 416,
    Unusable: 422,
    NoRoom: 507,
    Busy: 503,
}


def status_of(e: OmninavError) -> int:
    return next((code for kind, code in STATUS.items() if isinstance(e, kind)), 400)


class ApiError(Exception):
    """An HTTP-level refusal (authorisation, content type, rate, request shape): status and a
    message that says what was wrong. What the catalogue or the engine refuses is an OmninavError."""

    def __init__(self, status: int, message: str, **extra: Any):
        super().__init__(message)
        self.status = status
        self.message = message
        self.extra = extra


def error_response(status: int, message: str, **extra: Any) -> Any:
    resp = jsonify({"error": message, "status": status, **extra})
    resp.status_code = status
    return resp


def _retry_after(resp: Any, details: dict[str, Any]) -> None:
    """Retry-After, in whole seconds, where an answer's details say when to ask again."""
    if "retry_after_s" in details:
        resp.headers["Retry-After"] = str(max(1, math.ceil(details["retry_after_s"])))


def install_error_handlers(app: Flask) -> None:
    @app.errorhandler(ApiError)
    def _api(e: ApiError) -> Any:
        resp = error_response(e.status, e.message, **e.extra)
        if e.status == 429:
            _retry_after(resp, e.extra)
        if e.status == 401:
            resp.headers["WWW-Authenticate"] = 'Bearer realm="omninav admin"'
        return resp

    @app.errorhandler(OmninavError)
    def _engine(e: OmninavError) -> Any:  # the catalogue's and the engine's: their message is the answer
        resp = error_response(status_of(e), str(e), **e.details)
        _retry_after(resp, e.details)  # Busy: when the same request is likely to succeed
        return resp

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


JSON_MAX_DEPTH = 32  # nesting of a JSON body; the deepest this API reads (a feature record) is 4


def json_body(require_object: bool = True) -> Any:
    """The request's JSON body, or a 400 that says why it is not usable.

    Every JSON body comes through here, so hostile JSON stops here: text that is not UTF-8
    (RFC 8259; `json.loads` of bytes would let UTF-8-encoded surrogates through), nesting that
    exhausts the parser's recursion (or any later code's), and lone UTF-16 surrogates ("\\ud800"),
    which are no character: no database or file can store them.
    """
    if not request.is_json:
        raise ApiError(415, f"expected Content-Type application/json, got {request.content_type or 'none'}")
    raw = request.get_data(cache=True)
    too_deep = f"request body nests too deeply (at most {JSON_MAX_DEPTH} levels of arrays and objects)"
    try:
        text = raw.decode("utf-8-sig")
        obj = json.loads(text, parse_constant=_no_nan)
    except (UnicodeDecodeError, ValueError) as e:  # ValueError: JSONDecodeError, and ints past 4300 digits
        raise ApiError(400, f"request body is not valid JSON ({e})") from None
    except RecursionError:  # [[[[...]]]] thousands deep: the parser gives up before the end
        raise ApiError(400, too_deep) from None
    escapes = "\\u" in text  # in text that decoded as UTF-8, only an escape makes a lone surrogate
    if escapes or text.count("[") + text.count("{") > JSON_MAX_DEPTH:  # else it cannot nest too deeply
        problem = _json_problem(obj, escapes)
        if problem == "deep":
            raise ApiError(400, too_deep)
        if problem == "surrogate":
            raise ApiError(400, "request body holds a lone UTF-16 surrogate (\\ud800-\\udfff), which is no character")
    if require_object and not isinstance(obj, dict):
        raise ApiError(400, "request body must be a JSON object")
    return obj


def _json_problem(obj: Any, strings: bool) -> str | None:
    """'deep' if `obj` nests deeper than JSON_MAX_DEPTH, 'surrogate' if `strings` and a key or a
    string holds a lone surrogate, else None. Iterative: it must not recurse where the parser could not."""
    kinds = (str, dict, list) if strings else (dict, list)
    stack: list[tuple[Any, int]] = [(obj, 1)]
    while stack:
        v, depth = stack.pop()
        if isinstance(v, str):
            try:
                v.encode("utf-8")
            except UnicodeEncodeError:
                return "surrogate"
            continue
        if not isinstance(v, dict | list):  # a bare number or null as the whole body
            continue
        if depth > JSON_MAX_DEPTH:
            return "deep"
        children = [*v.keys(), *v.values()] if isinstance(v, dict) else v
        stack.extend((c, depth + 1) for c in children if isinstance(c, kinds))
    return None


def _no_nan(name: str) -> Any:
    raise ApiError(400, f"request body contains {name}, which JSON numbers cannot be")


def client_address() -> str:
    """The client, for the in-app rate limit. Behind `omninav serve` the workers listen on a unix
    socket that only nginx reaches, and nginx sets X-Forwarded-For to the one address it
    established; behind another proxy (TRUST_PROXY), the last entry is the one that proxy appended:
    everything left of it was written by the client and proves nothing."""
    fwd = request.headers.get("X-Forwarded-For", "")
    if fwd and (current_app.config["TRUST_PROXY"] or not request.remote_addr):
        return fwd.split(",")[-1].strip()
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
