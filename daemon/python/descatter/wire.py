"""The framing of docs/protocol.md, shared by the blocking and the asyncio client: one JSON line
per message, then the binary payloads its "payloads" array announces, back to back.
Nothing here does I/O."""
import json
from typing import Any

import numpy as np
import numpy.typing as npt

from .errors import BadReply

# A JSON object as the protocol sends it (a header, a result, an event's body).
JsonObject = dict[str, Any]
# A payload as decoded: a writable array of shape (height, width).
Image = npt.NDArray[Any]
PayloadSpec = tuple[str, "np.dtype[Any]", tuple[int, int], int]

DTYPES: dict[str, "np.dtype[Any]"] = {"u8": np.dtype("u1"), "u16": np.dtype("<u2"), "f32": np.dtype("<f4")}
MAX_LINE = 64 * 1024


def encode_request(request_id: int, cmd: str, args: JsonObject) -> bytes:
    request: JsonObject = {"id": request_id, "cmd": cmd}
    if args:
        request["args"] = args
    return json.dumps(request, allow_nan=False).encode() + b"\n"


def decode_header(line: bytes) -> JsonObject:
    """The header dict of one line; BadReply when it is not a protocol message."""
    try:
        header = json.loads(line)
    except (ValueError, UnicodeDecodeError) as e:
        raise BadReply(f"not JSON: {e}") from None
    if not isinstance(header, dict):
        raise BadReply("a message is a JSON object")
    return header


def payload_specs(header: JsonObject) -> list[PayloadSpec]:
    """[(name, dtype, shape, nbytes)] checked against each other: a wrong byte count would
    desynchronize the stream, so it is refused before anything is read."""
    specs: list[PayloadSpec] = []
    for p in header.get("payloads", []):
        try:
            dtype = DTYPES[p["dtype"]]
            shape = (int(p["height"]), int(p["width"]))
            nbytes = int(p["bytes"])
        except (KeyError, TypeError, ValueError):
            raise BadReply(f"payload description {p!r} is incomplete or of an unknown dtype") from None
        if nbytes != shape[0] * shape[1] * dtype.itemsize or min(shape) < 0:
            raise BadReply(f"payload {p.get('name')}: {nbytes} bytes, its shape {shape} needs "
                           f"{shape[0] * shape[1] * dtype.itemsize}")
        specs.append((str(p.get("name", f"payload{len(specs)}")), dtype, shape, nbytes))
    return specs


def new_array(dtype: "np.dtype[Any]", shape: tuple[int, int]) -> tuple[Image, memoryview]:
    """A writable array for a payload and the byte view to read it into."""
    array: Image = np.empty(shape, dtype=dtype)
    # numpy arrays export the buffer protocol; typeshed's memoryview() does not list them.
    return array, memoryview(array).cast("B")  # type: ignore[arg-type]
