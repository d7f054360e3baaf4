"""Python client of riskplan, the risk-bounded trajectory planning service (Zenoh).

    from riskplan import Client
    with Client("tcp/127.0.0.1:7447") as c:
        c.apply("demo", scene=scene_dict)
        plan = c.plan("demo", time_limit=10)
        print(plan.certified, plan.waypoints())
"""
from .client import Client, scene_key
from .errors import (
    ERRORS_BY_CODE,
    BusyError,
    DeadlineExceededError,
    UnavailableError,
    StaleRevisionError,
    ConnectError,
    DuplicateReplyError,
    InternalError,
    InvalidRequestError,
    InvalidSceneError,
    InvalidSceneNameError,
    InvalidTrajectoryError,
    LimitExceededError,
    MalformedPayloadError,
    NoPlanError,
    NoReplyError,
    OutsideWorkspaceError,
    PayloadTooLargeError,
    QueryTimeoutError,
    RiskplanError,
    UnknownSceneError,
    UnsafeEndpointError,
    UnsupportedEncodingError,
    error_from_reply,
)
from .plan import Plan, Trajectory

__version__ = "0.1.0"

__all__ = [
    "Client",
    "Plan",
    "Trajectory",
    "scene_key",
    "RiskplanError",
    "MalformedPayloadError",
    "UnsupportedEncodingError",
    "PayloadTooLargeError",
    "LimitExceededError",
    "InvalidSceneNameError",
    "UnknownSceneError",
    "InvalidSceneError",
    "InvalidRequestError",
    "InvalidTrajectoryError",
    "OutsideWorkspaceError",
    "UnsafeEndpointError",
    "NoPlanError",
    "BusyError",
    "DeadlineExceededError",
    "UnavailableError",
    "StaleRevisionError",
    "InternalError",
    "QueryTimeoutError",
    "NoReplyError",
    "DuplicateReplyError",
    "ConnectError",
    "ERRORS_BY_CODE",
    "error_from_reply",
]
