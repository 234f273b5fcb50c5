"""What the daemon sends besides replies, and the result of a capture, as plain objects."""
from typing import NamedTuple


class Result(NamedTuple):
    """A phase set's result: `meta` is the metadata of docs/protocol.md ("Result metadata"),
    `images` maps payload names ("transmissive", "scattered", "mask", ...) to writable numpy
    arrays of shape (height, width). Unpacks as `meta, images = client.capture()`."""

    meta: dict
    images: dict

    @property
    def set_id(self):
        return self.meta.get("set_id")

    @property
    def transmissive(self):
        return self.images.get("transmissive")

    @property
    def scattered(self):
        return self.images.get("scattered")

    @property
    def mask(self):
        return self.images.get("mask")

    @property
    def raw_frames(self):
        """With save_phases: [(phase, frame_id, array)] in acquisition order (meta["raw_frames"]);
        [] otherwise."""
        frames = (self.meta.get("raw_frames") or {}).get("frames") or []
        return [(f["phase"], f.get("frame_id"), self.images[f["payload"]]) for f in frames]

    @property
    def black(self):
        """With save_phases and a dark frame: the dark frame the daemon subtracted, else None."""
        return self.images.get("black") if self.meta.get("raw_frames") else None


class Event:
    """A message from a subscription. `seq` counts every event the daemon publishes; `lost` is
    how many this client missed just before this one (it read too slowly: the daemon dropped
    them, docs/protocol.md)."""

    kind = "event"

    def __init__(self, seq, lost, body):
        self.seq, self.lost, self.body = seq, lost, body

    def __repr__(self):
        return f"<{type(self).__name__} seq={self.seq} lost={self.lost}>"


class ResultEvent(Event):
    """A published result (continuous acquisition, or another client's capture)."""

    kind = "result"

    def __init__(self, seq, lost, body, images):
        super().__init__(seq, lost, body)
        self.result = Result(body, images)

    @property
    def meta(self):
        return self.result.meta

    @property
    def images(self):
        return self.result.images


class FailedEvent(Event):
    """A phase set failed; `reason` says why."""

    kind = "failed"

    @property
    def reason(self):
        return self.body.get("reason", "")


class DeviceEvent(Event):
    """A device changed state (lost, reconnecting, back); `message` says which and how."""

    kind = "device"

    @property
    def message(self):
        return self.body.get("message", "")


class ProgressEvent(Event):
    """A phase of a capture was acquired (captures ask for these to keep the line alive)."""

    kind = "progress"

    @property
    def phase(self):
        return self.body.get("phase")

    @property
    def phases(self):
        return self.body.get("phases")


class FrameEvent(Event):
    """A preview frame (subscribe(frames=True) while preview runs): `frame` is the camera's
    image as a numpy array (uint8 or uint16, shape (height, width)); `light` is "all", "off" or
    "phase", `phase` the phase lit (None unless light is "phase"). Frames have their own `seq`,
    so `lost` counts frames this client missed, not results."""

    kind = "frame"

    def __init__(self, seq, lost, body, images):
        super().__init__(seq, lost, body)
        self.frame = images.get("frame")

    @property
    def light(self):
        return self.body.get("light")

    @property
    def phase(self):
        return self.body.get("phase")

    @property
    def frame_id(self):
        return self.body.get("frame_id")


_KINDS = {"failed": FailedEvent, "device": DeviceEvent, "progress": ProgressEvent}


def _lost(seq, last_seq):
    return seq - last_seq - 1 if isinstance(seq, int) and last_seq is not None and seq > last_seq + 1 else 0


def make_frame_event(header, images, last_frame_seq):
    """(FrameEvent, new last frame seq) for a `frame` event: frames count their own seq."""
    seq = header.get("seq")
    ev = FrameEvent(seq, _lost(seq, last_frame_seq), header.get("body") or {}, images)
    return ev, seq if isinstance(seq, int) else last_frame_seq


def make_event(header, images, last_seq):
    """(event, new last_seq) for an event message; the gap in seq is the events lost."""
    kind = header.get("event")
    body = header.get("body") or {}
    if kind == "progress":  # per request, not counted in seq
        return ProgressEvent(None, 0, body), last_seq
    seq = header.get("seq")
    lost = seq - last_seq - 1 if isinstance(seq, int) and last_seq is not None and seq > last_seq + 1 else 0
    new_last = seq if isinstance(seq, int) else last_seq
    if kind == "result":
        return ResultEvent(seq, lost, body, images), new_last
    cls = _KINDS.get(kind)
    if cls is None:  # a newer daemon's event: still surfaced, as a plain Event
        ev = Event(seq, lost, body)
        ev.kind = kind
        return ev, new_last
    return cls(seq, lost, body), new_last
