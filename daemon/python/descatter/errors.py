"""Exceptions: one class per stable error code of the protocol (docs/protocol.md), so that a
caller catches exactly what it can handle:

    try:
        client.capture(phases=1)
    except descatter.BadArgument as e:
        print(e.code, e.message)

Every class derives from DescatterError; `code` is the wire name, `message` the daemon's text.
"""


from typing import Any, Optional


class DescatterError(Exception):
    """A reply with ok=false (or a client-side failure with a protocol code)."""

    code: str = "failed"

    def __init__(self, message: str, code: Optional[str] = None) -> None:
        if code is not None:
            self.code = code
        super().__init__(f"{self.code}: {message}")
        self.message = message


class LineTooLong(DescatterError):
    code = "line_too_long"


class BadJson(DescatterError):
    code = "bad_json"


class TooDeep(DescatterError):
    code = "too_deep"


class BadRequest(DescatterError):
    code = "bad_request"


class UnknownCommand(DescatterError):
    code = "unknown_command"


class BadArgument(DescatterError, ValueError):
    code = "bad_argument"


class Busy(DescatterError):
    code = "busy"


class DeviceError(DescatterError):
    code = "device_error"


class Unauthorized(DescatterError, PermissionError):
    code = "unauthorized"


class Limit(DescatterError):
    code = "limit"


class Failed(DescatterError):
    code = "failed"


class Cancelled(DescatterError):
    code = "cancelled"


class BadReply(DescatterError):
    """The daemon's message did not parse (client side): the connection is out of sync."""

    code = "bad_reply"


class Timeout(DescatterError, TimeoutError):
    """Nothing arrived from the daemon for `timeout` seconds (client side).

    What happens to the connection: it stays open and usable. The reply that comes late is
    recognised by its request id and dropped; events that come meanwhile still reach the
    subscription. Only the blocking client, when the silence falls in the middle of a message
    (a header line or a payload half read), closes its connection: the next bytes could not be
    told apart from a new message. The asyncio client's reader never stops on a timeout.

    What happens in the daemon: a `capture`, `calibrate` or `dark` that times out has sent
    `cancel` on a second connection and waited for its reply before this was raised, so the
    daemon does not go on acquiring for nobody (docs/python.md, "Timeouts"); that `cancel`
    stops all acquisition, other clients' captures and continuous mode included.
    `cancel_reply` is its reply ({"cancelled", "stream_stopped", "state"}), or None with
    `cancel_error` saying why it could not be sent. Both are None for other requests (their
    request may still run to its end in the daemon)."""

    code = "timeout"
    cancel_reply: Optional[dict[str, Any]] = None
    cancel_error: Optional[BaseException] = None


ERRORS: dict[str, type[DescatterError]] = {
    cls.code: cls for cls in (LineTooLong, BadJson, TooDeep, BadRequest, UnknownCommand, BadArgument, Busy,
                              DeviceError, Unauthorized, Limit, Failed, Cancelled, BadReply)}


def error_from_reply(error: Any) -> DescatterError:
    """The exception for a reply's "error" object; an unknown code (a newer daemon) is a
    DescatterError carrying that code."""
    code = error.get("code", "failed") if isinstance(error, dict) else "failed"
    message = error.get("message", "") if isinstance(error, dict) else str(error)
    cls = ERRORS.get(code)
    return cls(message) if cls else DescatterError(message, code=code)
