"""Exceptions: one class per stable error code of the protocol (docs/protocol.md), so that a
caller catches exactly what it can handle:

    try:
        client.capture(phases=1)
    except descatter.BadArgument as e:
        print(e.code, e.message)

Every class derives from DescatterError; `code` is the wire name, `message` the daemon's text.
"""


class DescatterError(Exception):
    """A reply with ok=false (or a client-side failure with a protocol code)."""

    code = "failed"

    def __init__(self, message, code=None):
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
    """No message from the daemon within the timeout (client side). A timeout before a message
    started leaves the connection usable (the late reply is skipped by its id); one in the middle
    of a message closes it (the stream would be out of sync).

    A capture, calibrate or dark that times out has sent `cancel` on a second connection before
    this was raised, so that the daemon stops acquiring for nobody (docs/python.md, "Timeouts"):
    `cancel_reply` is the cancel's reply ({"cancelled", "stream_stopped", "state"}), or None
    with `cancel_error` saying why it could not be sent. None on other requests."""

    code = "timeout"
    cancel_reply = None
    cancel_error = None


ERRORS = {cls.code: cls for cls in (LineTooLong, BadJson, TooDeep, BadRequest, UnknownCommand, BadArgument,
                                     Busy, DeviceError, Unauthorized, Limit, Failed, Cancelled, BadReply)}


def error_from_reply(error):
    """The exception for a reply's "error" object; an unknown code (a newer daemon) is a
    DescatterError carrying that code."""
    code = error.get("code", "failed") if isinstance(error, dict) else "failed"
    message = error.get("message", "") if isinstance(error, dict) else str(error)
    cls = ERRORS.get(code)
    return cls(message) if cls else DescatterError(message, code=code)
