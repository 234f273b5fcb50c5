"""descatter: the Python client of descatterd, the near-infrared transmissive descattering lab
service (docs/python.md, docs/protocol.md).

    import descatter
    with descatter.Client() as c:              # $DESCATTER_ADDRESS or /run/descatterd/descatterd.sock
        r = c.capture(phases=8)
        r.transmissive, r.scattered, r.mask    # writable numpy arrays (height, width)

descatter.aio has the same commands for asyncio (`async with descatter.aio.connect() as c`).
The package is typed (py.typed; mypy --strict clean).
"""
from ._version import __version__
from .client import DEFAULT_ADDRESS, DEFAULT_TIMEOUT, Client, Subscription
from .errors import (ERRORS, BadArgument, BadJson, BadReply, BadRequest, Busy, Cancelled, DescatterError,
                     DeviceError, Failed, LineTooLong, Limit, Timeout, TooDeep, Unauthorized, UnknownCommand)
from .events import (DeviceEvent, Event, FailedEvent, FrameEvent, ProgressEvent, Result, ResultEvent, StreamStoppedEvent,
                     WindowBrokenEvent)

__all__ = [
    "__version__", "Client", "Subscription", "DEFAULT_ADDRESS", "DEFAULT_TIMEOUT",
    "Result", "Event", "ResultEvent", "FailedEvent", "DeviceEvent", "ProgressEvent", "FrameEvent",
    "StreamStoppedEvent", "WindowBrokenEvent",
    "DescatterError", "ERRORS", "LineTooLong", "BadJson", "TooDeep", "BadRequest", "UnknownCommand",
    "BadArgument", "Busy", "DeviceError", "Unauthorized", "Limit", "Failed", "Cancelled", "BadReply", "Timeout",
]
