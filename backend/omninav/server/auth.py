"""Admin authentication: one bearer token, stored only as its SHA-256.

The token is made at first start and printed once (serve.py); OMNINAV_ADMIN_TOKEN sets it instead.
`omninav admin-token --reset` makes a new one when it is lost.
"""

from __future__ import annotations

import hashlib
import hmac
import secrets

from flask import current_app, request

from ..catalog.db import Db
from .http import ApiError

KEY = "admin_token_sha256"
UNAUTHORISED = "admin calls need 'Authorization: Bearer <admin token>' (printed at first start)"
FORBIDDEN = "wrong admin token"


def _digest(token: str) -> str:
    return hashlib.sha256(token.encode()).hexdigest()


def set_token(db: Db, token: str | None = None) -> str:
    token = token or secrets.token_urlsafe(24)
    db.set_meta(KEY, _digest(token))
    return token


def ensure_token(db: Db) -> str | None:
    """A new token if there is none yet (returned, to be shown once), else None."""
    if db.get_meta(KEY):
        return None
    return set_token(db)


def require_admin() -> None:
    """before_request of the admin blueprints: no admin call without the token."""
    head = request.headers.get("Authorization", "")
    scheme, _, token = head.partition(" ")
    if scheme.lower() != "bearer" or not token.strip():
        raise ApiError(401, UNAUTHORISED)
    want = current_app.extensions["omninav"].db.get_meta(KEY)
    if not want or not hmac.compare_digest(_digest(token.strip()), want):
        raise ApiError(403, FORBIDDEN)
