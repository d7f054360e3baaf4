"""Errors of the riskplan client.

Every error is a :class:`RiskplanError` carrying ``code``, ``message`` and ``field``.
Server errors (``reply_err`` with a JSON ``{"code", "message", "field"}`` payload) map to
one subclass per documented code (proto/README.md, "Error codes"); an unknown code gives
a plain :class:`RiskplanError`. Three codes are client-side: ``timeout`` (the query timed
out: the server is hung or slower than the timeout), ``no_reply`` (the query ended
with no reply at all: no server, or the server died while handling it) and
``duplicate_reply`` (more than one reply to one query: the protocol promises exactly one).
"""
from __future__ import annotations

from typing import Dict, Optional, Type


class RiskplanError(Exception):
    """Base class: an error reply of the server, or a client-side failure."""

    code: str = "unknown"

    def __init__(self, message: str = "", code: Optional[str] = None, field: Optional[str] = None):
        super().__init__(message)
        if code is not None:
            self.code = code
        self.message = message
        self.field = field

    def __str__(self) -> str:
        where = f" (field {self.field})" if self.field else ""
        return f"{self.code}: {self.message}{where}"

    def __repr__(self) -> str:
        return f"{type(self).__name__}(code={self.code!r}, message={self.message!r}, field={self.field!r})"


class MalformedPayloadError(RiskplanError, ValueError):
    """The payload does not parse as the message (bad JSON, wrong types, unknown fields)."""

    code = "malformed_payload"


class UnsupportedEncodingError(RiskplanError, ValueError):
    """An encoding other than JSON or bincode."""

    code = "unsupported_encoding"


class PayloadTooLargeError(RiskplanError, ValueError):
    """Over MAX_PAYLOAD_BYTES (1 MiB)."""

    code = "payload_too_large"


class LimitExceededError(RiskplanError, ValueError):
    """A documented limit (points per risk query, grid side, scene limits)."""

    code = "limit_exceeded"


class InvalidSceneNameError(RiskplanError, ValueError):
    """A scene name outside ``A-Z a-z 0-9 _ - .`` (1-128 characters)."""

    code = "invalid_scene_name"


class UnknownSceneError(RiskplanError, KeyError):
    """No scene by that name."""

    code = "unknown_scene"

    def __str__(self) -> str:  # KeyError would repr() the message
        return RiskplanError.__str__(self)


class InvalidSceneError(RiskplanError, ValueError):
    """The scene (or a change) fails validation; ``field`` names the field."""

    code = "invalid_scene"


class InvalidRequestError(RiskplanError, ValueError):
    """A field out of range (Δ, time limit, pieces, method, dimension, ...)."""

    code = "invalid_request"


class InvalidTrajectoryError(RiskplanError, ValueError):
    """The trajectory fails validation."""

    code = "invalid_trajectory"


class OutsideWorkspaceError(RiskplanError, ValueError):
    """Start or goal outside the workspace."""

    code = "outside_workspace"


class UnsafeEndpointError(RiskplanError, ValueError):
    """Start or goal not strictly inside every Δ-risk contour."""

    code = "unsafe_endpoint"


class NoPlanError(RiskplanError):
    """No plan within the time limit or the planner's limits."""

    code = "no_plan"


class BusyError(RiskplanError):
    """The server's job queue is full: try again later."""

    code = "busy"


class DeadlineExceededError(RiskplanError, TimeoutError):
    """The request's deadline (``deadline_ms``, or the plan's time limit) passed on the
    server, in the queue or during the work: nothing was decided."""

    code = "deadline_exceeded"


class UnavailableError(RiskplanError):
    """The server cannot take requests yet: it is loading its stored scenes (its
    ``status()["state"]`` is ``"loading"``). Safe to retry shortly."""

    code = "unavailable"


class StaleRevisionError(RiskplanError):
    """The read asked for a revision of its scene (``min_revision``, see
    :meth:`Client.at_least`) that the server answering it does not have yet — a replica
    behind its primary — after waiting briefly for it. Retry, or ask another server."""

    code = "stale_revision"


class InternalError(RiskplanError):
    """A bug on the server's side (a caught panic)."""

    code = "internal"


class QueryTimeoutError(RiskplanError, TimeoutError):
    """The query timed out (Zenoh's ``Timeout`` error reply): the server is hung or
    the work took longer than the client's timeout. ``code == "timeout"``."""

    code = "timeout"


class NoReplyError(RiskplanError, ConnectionError):
    """The query ended with no reply at all: no server serves the key (absent, or it
    died while handling the query), or the deployment's access control denied the
    query (a reader's ``apply``: Zenoh drops denied messages silently, deploy/secure).
    ``code == "no_reply"``. Safe to retry."""

    code = "no_reply"


class DuplicateReplyError(RiskplanError):
    """More than one reply (success or error) to one query, where the protocol promises
    exactly one: two servers serve the same key on this Zenoh network, or a server
    answered twice. No reply is used. ``code == "duplicate_reply"``; ``count`` is the
    number of replies."""

    code = "duplicate_reply"

    def __init__(self, message: str = "", code: Optional[str] = None, field: Optional[str] = None,
                 count: Optional[int] = None):
        super().__init__(message, code=code, field=field)
        self.count = count


class ConnectError(RiskplanError, ConnectionError):
    """The Zenoh session could not be opened (nothing listens on the endpoint)."""

    code = "connect"


ERRORS_BY_CODE: Dict[str, Type[RiskplanError]] = {
    cls.code: cls
    for cls in (
        MalformedPayloadError,
        UnsupportedEncodingError,
        PayloadTooLargeError,
        LimitExceededError,
        InvalidSceneNameError,
        UnknownSceneError,
        InvalidSceneError,
        InvalidRequestError,
        InvalidTrajectoryError,
        OutsideWorkspaceError,
        UnsafeEndpointError,
        NoPlanError,
        BusyError,
        DeadlineExceededError,
        UnavailableError,
        StaleRevisionError,
        InternalError,
        QueryTimeoutError,
        NoReplyError,
        DuplicateReplyError,
        ConnectError,
    )
}


def error_from_reply(payload: dict) -> RiskplanError:
    """The exception for an ``error`` payload ``{"code", "message", "field"}``."""
    code = str(payload.get("code", "unknown"))
    message = str(payload.get("message", ""))
    field = payload.get("field")
    cls = ERRORS_BY_CODE.get(code, RiskplanError)
    return cls(message, code=code, field=field)
