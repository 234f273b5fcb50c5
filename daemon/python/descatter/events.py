"""What the daemon sends besides replies, and the result of a capture, as plain objects."""
from typing import Any, NamedTuple, Optional

from .wire import Image, JsonObject


class Result(NamedTuple):
    """A phase set's result: `meta` is the metadata of docs/protocol.md ("Result metadata"),
    `images` maps payload names ("transmissive", "scattered", "mask", ...) to writable numpy
    arrays of shape (height, width). Unpacks as `meta, images = client.capture()`. Its repr is
    one short line (set id, estimator, N, the payloads with shape and dtype), not the arrays."""

    meta: JsonObject
    images: dict[str, Image]

    def __repr__(self) -> str:
        sep = self.meta.get("separation") or {}
        how = f" {sep['estimator']} N={sep.get('phases')}" if isinstance(sep, dict) and "estimator" in sep else ""
        payloads = ", ".join(f"{name} {'x'.join(map(str, a.shape))} {a.dtype}" for name, a in self.images.items())
        return f"<Result set {self.set_id}{how}: {payloads or 'no payloads'}>"

    @property
    def set_id(self) -> Optional[int]:
        set_id = self.meta.get("set_id")
        return set_id if isinstance(set_id, int) else None

    @property
    def transmissive(self) -> Optional[Image]:
        return self.images.get("transmissive")

    @property
    def scattered(self) -> Optional[Image]:
        return self.images.get("scattered")

    @property
    def mask(self) -> Optional[Image]:
        return self.images.get("mask")

    @property
    def raw_frames(self) -> list[tuple[int, Optional[int], Image]]:
        """With save_phases: [(phase, frame_id, array)] in acquisition order (meta["raw_frames"]);
        [] otherwise."""
        frames = (self.meta.get("raw_frames") or {}).get("frames") or []
        return [(f["phase"], f.get("frame_id"), self.images[f["payload"]]) for f in frames]

    @property
    def black(self) -> Optional[Image]:
        """With save_phases and a dark frame: the dark frame the daemon subtracted, else None."""
        return self.images.get("black") if self.meta.get("raw_frames") else None


class Event:
    """A message from a subscription. `seq` counts every event the daemon publishes; `lost` is
    how many this client missed just before this one (it read too slowly: the daemon dropped
    them, docs/protocol.md). `kind` is the wire name ("result", "failed", "device", or a
    newer daemon's kind on a plain Event)."""

    kind: str = "event"

    def __init__(self, seq: Optional[int], lost: int, body: JsonObject) -> None:
        self.seq, self.lost, self.body = seq, lost, body

    def __repr__(self) -> str:
        return f"<{type(self).__name__} seq={self.seq} lost={self.lost}>"


class ResultEvent(Event):
    """A published result (continuous acquisition, or another client's capture). `skipped`: the
    results published since the previous one this client got that it was not sent (it read too
    slowly; per-frame results then come newest first, docs/protocol.md "Events")."""

    kind = "result"

    def __init__(self, seq: Optional[int], lost: int, body: JsonObject, images: dict[str, Image],
                 skipped: int = 0) -> None:
        super().__init__(seq, lost, body)
        self.result = Result(body, images)
        self.skipped = skipped

    def __repr__(self) -> str:
        return f"<ResultEvent seq={self.seq} lost={self.lost} {self.result!r}>"

    @property
    def meta(self) -> JsonObject:
        return self.result.meta

    @property
    def images(self) -> dict[str, Image]:
        return self.result.images


class FailedEvent(Event):
    """A phase set failed; `reason` says why."""

    kind = "failed"

    @property
    def reason(self) -> str:
        return str(self.body.get("reason", ""))


class DeviceEvent(Event):
    """A device changed state (lost, reconnecting, back); `message` says which and how."""

    kind = "device"

    @property
    def message(self) -> str:
        return str(self.body.get("message", ""))


class StreamStoppedEvent(Event):
    """Continuous acquisition stopped by itself: its sets kept failing ([acquisition]
    max-failed-sets in a row); `reason` says when and why."""

    kind = "stream_stopped"

    @property
    def reason(self) -> str:
        return str(self.body.get("reason", ""))


class WindowBrokenEvent(Event):
    """Per-frame results: the sliding window was broken (a lost or refused frame, new
    settings); no result until a good frame of every phase follows. `reason` is the cause's
    name (frame_gap, wrong_phase, lost, ...), `message` says more."""

    kind = "window_broken"

    @property
    def reason(self) -> str:
        return str(self.body.get("reason", ""))

    @property
    def message(self) -> str:
        return str(self.body.get("message", ""))


class ProgressEvent(Event):
    """A phase of a capture was acquired (captures ask for these to keep the line alive)."""

    kind = "progress"

    @property
    def phase(self) -> Optional[int]:
        phase: Any = self.body.get("phase")
        return phase if isinstance(phase, int) else None

    @property
    def phases(self) -> Optional[int]:
        phases: Any = self.body.get("phases")
        return phases if isinstance(phases, int) else None


class FrameEvent(Event):
    """A preview frame (subscribe(frames=True) while preview runs): `frame` is the camera's
    image as a numpy array (uint8 or uint16, shape (height, width)); `light` is "all", "off" or
    "phase", `phase` the phase lit (None unless light is "phase"). Frames have their own `seq`,
    so `lost` counts frames this client missed, not results."""

    kind = "frame"

    def __init__(self, seq: Optional[int], lost: int, body: JsonObject, images: dict[str, Image]) -> None:
        super().__init__(seq, lost, body)
        self.frame: Optional[Image] = images.get("frame")

    @property
    def light(self) -> Optional[str]:
        light: Any = self.body.get("light")
        return light if isinstance(light, str) else None

    @property
    def phase(self) -> Optional[int]:
        phase: Any = self.body.get("phase")
        return phase if isinstance(phase, int) else None

    @property
    def frame_id(self) -> Optional[int]:
        frame_id: Any = self.body.get("frame_id")
        return frame_id if isinstance(frame_id, int) else None


_KINDS: dict[str, type[Event]] = {"failed": FailedEvent, "device": DeviceEvent, "stream_stopped": StreamStoppedEvent,
                                  "progress": ProgressEvent, "window_broken": WindowBrokenEvent}


def _lost(seq: Any, last_seq: Optional[int]) -> int:
    return seq - last_seq - 1 if isinstance(seq, int) and last_seq is not None and seq > last_seq + 1 else 0


def make_frame_event(header: JsonObject, images: dict[str, Image],
                     last_frame_seq: Optional[int]) -> tuple[FrameEvent, Optional[int]]:
    """(FrameEvent, new last frame seq) for a `frame` event: frames count their own seq."""
    seq: Any = header.get("seq")
    body: Any = header.get("body") or {}
    ev = FrameEvent(seq if isinstance(seq, int) else None, _lost(seq, last_frame_seq), body, images)
    return ev, seq if isinstance(seq, int) else last_frame_seq


def make_event(header: JsonObject, images: dict[str, Image], last_seq: Optional[int]) -> tuple[Event, Optional[int]]:
    """(event, new last_seq) for an event message; the gap in seq is the events lost."""
    kind = str(header.get("event"))
    body = header.get("body") or {}
    if kind == "progress":  # per request, not counted in seq
        return ProgressEvent(None, 0, body), last_seq
    seq = header.get("seq")
    lost = _lost(seq, last_seq)
    new_last = seq if isinstance(seq, int) else last_seq
    if kind == "result":
        skipped: Any = header.get("skipped")
        return ResultEvent(seq, lost, body, images, skipped if isinstance(skipped, int) else 0), new_last
    cls = _KINDS.get(kind)
    if cls is None:  # a newer daemon's event: still surfaced, as a plain Event
        ev = Event(seq, lost, body)
        ev.kind = kind
        return ev, new_last
    return cls(seq, lost, body), new_last
