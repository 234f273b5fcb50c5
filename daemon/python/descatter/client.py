"""The blocking client of descatterd (docs/protocol.md, docs/python.md).

    import descatter
    with descatter.Client("/run/descatterd/descatterd.sock") as c:
        r = c.capture(phases=8)
        print(r.set_id, r.transmissive.mean())
        with c.subscribe() as sub:
            c.start(phases=8)
            for ev in sub:
                ...

One thread at a time per client. Every wait for the daemon is bounded by `timeout` seconds of
silence (captures ask for progress events, so a long set keeps the line alive); a reply that
does not come in time raises descatter.Timeout, after cancelling the daemon's acquisition when
the request was a capture, calibrate or dark (Client.cancel).

The acquisition settings are keyword parameters with types (None, the default: the daemon's
configuration decides); a misspelt one is Python's TypeError before anything is sent.
"""
import collections
import os
import select
import socket
from collections.abc import Callable, Iterable, Iterator
from types import TracebackType
from typing import Any, Literal, Optional, Union

from . import wire
from ._version import __version__
from .errors import BadReply, DescatterError, Timeout, error_from_reply
from .events import Event, ProgressEvent, Result, ResultEvent, make_event, make_frame_event
from .wire import Image, JsonObject

DEFAULT_ADDRESS = "/run/descatterd/descatterd.sock"
DEFAULT_TIMEOUT = 60.0

# The estimators of docs/protocol.md; a newer daemon may know more (any str is sent).
Estimator = Union[Literal["maxmin", "sine", "robust"], str]
# The payload format of a capture.
Format = Literal["f32", "u16"]
Results = Literal["per-set", "per-frame"]
ProgressCallback = Callable[[ProgressEvent], None]


def resolve(address: Optional[str], token: Optional[str]) -> tuple[str, Optional[str]]:
    """The address and token in use: given, else $DESCATTER_ADDRESS / $DESCATTER_TOKEN (as for
    descatterctl), else the default socket and no token."""
    address = address or os.environ.get("DESCATTER_ADDRESS") or DEFAULT_ADDRESS
    if token is None:
        token = os.environ.get("DESCATTER_TOKEN") or None
    return address, token


def split_address(address: str) -> tuple[str, Union[str, tuple[str, int]]]:
    """("tcp", (host, port)) or ("unix", path) for "tcp:HOST:PORT", "unix:PATH" or a path."""
    if address.startswith("tcp:"):
        host, sep, port = address[4:].rpartition(":")
        if not sep or not host or not port.isdigit() or not 0 < int(port) < 65536:
            raise ValueError(f"address {address!r}: expected tcp:HOST:PORT")
        return "tcp", (host.strip("[]"), int(port))
    return "unix", address[5:] if address.startswith("unix:") else address


def given(**kwargs: Any) -> JsonObject:
    """The arguments given (None = not given: the daemon's configuration decides)."""
    return {k: v for k, v in kwargs.items() if v is not None}


def acquisition_args(*, phases: Optional[int], averages: Optional[int], exposure_us: Optional[float],
                     gain_db: Optional[float], estimator: Optional[str], dark_frame: Optional[bool],
                     verify_phase: Optional[bool], target_error: Optional[float],
                     time_budget_ms: Optional[float], save_phases: Optional[bool],
                     single_frame: Optional[bool] = None, speed_px_s: Optional[float] = None) -> JsonObject:
    """The settings of capture and start (docs/protocol.md, `capture`), as sent."""
    return given(phases=phases, averages=averages, exposure_us=exposure_us, gain_db=gain_db, estimator=estimator,
                 dark_frame=dark_frame, verify_phase=verify_phase, target_error=target_error,
                 time_budget_ms=time_budget_ms, speed_px_s=speed_px_s, save_phases=save_phases,
                 single_frame=single_frame)


Roi = Union[tuple[int, int, int, int], dict[str, int]]
PreviewLight = Literal["all", "off", "phase"]


def preview_args(on: bool, light: PreviewLight, phase: Optional[int]) -> JsonObject:
    """The arguments of `preview`: state, and the light and phase when on."""
    if not on:
        return {"state": "off"}
    args: JsonObject = {"state": "on", "light": light}
    if phase is not None:
        args["phase"] = phase
    return args


def camera_args(exposure_us: Optional[float] = None, gain_db: Optional[float] = None,
                roi: Optional[Roi] = None) -> JsonObject:
    """The arguments of `set`: the ones given. roi: (x, y, width, height) or a dict of those."""
    args = given(exposure_us=exposure_us, gain_db=gain_db)
    if roi is not None:
        values: tuple[Any, ...]
        if isinstance(roi, dict):
            values = tuple(roi.get(k) for k in ("x", "y", "width", "height"))
        else:
            values = tuple(roi)
        if len(values) != 4 or not all(isinstance(v, int) and not isinstance(v, bool) for v in values):
            raise TypeError("roi: (x, y, width, height), four ints (pixels on the sensor)")
        args["roi"] = dict(zip(("x", "y", "width", "height"), values))
    if not args:
        raise TypeError("set_camera: give exposure_us, gain_db or roi")
    return args


class Client:
    """A connection to descatterd. address: a UNIX socket path, "unix:PATH" or "tcp:HOST:PORT"
    (None: $DESCATTER_ADDRESS, else the default socket); token: the daemon's TCP token, sent in
    hello at once (None: $DESCATTER_TOKEN); timeout: seconds of silence allowed while waiting
    for the daemon. Connects in the constructor (OSError when nobody listens); a wrong token
    raises descatter.Unauthorized there. A context manager that closes the connection."""

    def __init__(self, address: Optional[str] = None, token: Optional[str] = None,
                 timeout: float = DEFAULT_TIMEOUT) -> None:
        self.address, self.token = resolve(address, token)
        self.timeout = timeout
        _, where = split_address(self.address)
        sock: socket.socket
        if isinstance(where, tuple):
            sock = socket.create_connection(where, timeout=timeout)
        else:
            sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
            sock.settimeout(timeout)
            try:
                sock.connect(where)
            except OSError:
                sock.close()
                raise
        sock.setblocking(True)
        sock.settimeout(None)
        self._sock: Optional[socket.socket] = sock
        self._buf = bytearray()
        self._next_id = 0
        self._events: collections.deque[Event] = collections.deque()  # read while waiting for a reply
        self._subscribed = False
        self._last_seq: Optional[int] = None
        self._last_frame_seq: Optional[int] = None
        self._broken: Optional[str] = None
        if self.token:
            try:
                self.hello()
            except BaseException:
                self.close()
                raise

    def __repr__(self) -> str:
        state = "open" if self._sock is not None else "closed"
        return f"<descatter.Client {self.address} {state}>"

    # -- connection --------------------------------------------------------------------------

    def close(self) -> None:
        """Closes the connection (the daemon forgets this client's subscription); idempotent."""
        if self._sock is not None:
            self._sock.close()
            self._sock = None

    def __enter__(self) -> "Client":
        return self

    def __exit__(self, exc_type: Optional[type[BaseException]], exc: Optional[BaseException],
                 tb: Optional[TracebackType]) -> None:
        self.close()

    def _fail(self, exc: BaseException) -> Any:
        """The stream is out of sync: nothing more can be read from this connection."""
        self._broken = str(exc)
        self.close()
        raise exc

    def _connected(self) -> socket.socket:
        if self._sock is None:
            raise ConnectionError(f"connection closed ({self._broken or 'closed by the caller'})")
        return self._sock

    def _fill(self, timeout: float, mid_message: bool) -> None:
        sock = self._connected()
        ready, _, _ = select.select([sock], [], [], timeout)
        if not ready:
            exc = Timeout(f"no message from descatterd in {timeout:g} s")
            if mid_message:
                self._fail(exc)
            raise exc
        chunk = sock.recv(1 << 20)
        if not chunk:
            self._fail(ConnectionError("descatterd closed the connection"))
        self._buf += chunk

    def _read_line(self, timeout: float) -> bytes:
        start = 0
        while True:
            nl = self._buf.find(b"\n", start)
            if nl >= 0:
                line = bytes(self._buf[:nl])
                del self._buf[:nl + 1]
                return line
            if len(self._buf) > wire.MAX_LINE + 1:
                self._fail(BadReply(f"a line longer than {wire.MAX_LINE} bytes"))
            start = len(self._buf)
            self._fill(timeout, mid_message=bool(self._buf))

    def _read_into(self, view: memoryview, timeout: float) -> None:
        n = min(len(view), len(self._buf))
        view[:n] = self._buf[:n]
        del self._buf[:n]
        sock = self._connected()
        while n < len(view):
            ready, _, _ = select.select([sock], [], [], timeout)
            if not ready:
                self._fail(Timeout(f"payload stalled for {timeout:g} s"))
            got = sock.recv_into(view[n:])
            if got == 0:
                self._fail(ConnectionError("descatterd closed the connection mid-payload"))
            n += got

    def read_message(self, timeout: Optional[float] = None) -> tuple[JsonObject, dict[str, Image]]:
        """The next message as (header dict, {payload name: writable numpy array}). timeout:
        seconds to wait for it (None: the client's). Raises Timeout: before the message started
        the connection stays usable, in the middle of it the connection is closed."""
        limit = self.timeout if timeout is None else timeout
        try:
            header = wire.decode_header(self._read_line(limit))
            images: dict[str, Image] = {}
            for name, dtype, shape, nbytes in wire.payload_specs(header):
                array, view = wire.new_array(dtype, shape)
                if nbytes:
                    self._read_into(view, limit)
                images[name] = array
            return header, images
        except BadReply as e:
            return self._fail(e)  # type: ignore[no-any-return]

    # -- requests ----------------------------------------------------------------------------

    def _queue_event(self, header: JsonObject, images: dict[str, Image],
                     on_progress: Optional[ProgressCallback]) -> None:
        ev: Event
        if header.get("event") == "frame":
            ev, self._last_frame_seq = make_frame_event(header, images, self._last_frame_seq)
        else:
            ev, self._last_seq = make_event(header, images, self._last_seq)
        if isinstance(ev, ProgressEvent):
            if on_progress:
                on_progress(ev)
        elif self._subscribed:
            self._events.append(ev)

    def call(self, cmd: str, timeout: Optional[float] = None, on_progress: Optional[ProgressCallback] = None,
             **args: Any) -> tuple[JsonObject, dict[str, Image]]:
        """Sends any command with `args` as its JSON arguments (no check here: the daemon's
        bad_argument names what it refuses) and returns (result dict, images). A reply with
        ok=false raises the exception of its code (descatter.BadArgument, descatter.Busy, ...).
        Events that arrive meanwhile are kept for the subscription (progress events go to
        on_progress)."""
        self._next_id += 1
        rid = self._next_id
        self._connected().sendall(wire.encode_request(rid, cmd, args))
        while True:
            header, images = self.read_message(timeout)
            if "event" in header:
                self._queue_event(header, images, on_progress)
                continue
            if header.get("id") != rid:
                continue  # a reply to an earlier request that timed out on our side
            if not header.get("ok"):
                raise error_from_reply(header.get("error", {}))
            return header.get("result") or {}, images

    def hello(self) -> JsonObject:
        """Names this client (and sends the token); returns the daemon's version, git and state."""
        args: JsonObject = {"client": f"descatter-python/{__version__}"}
        if self.token:
            args["token"] = self.token
        return self.call("hello", **args)[0]

    def status(self) -> JsonObject:
        """The daemon's state, devices, counters and settings (docs/protocol.md, `status`)."""
        return self.call("status")[0]

    def config(self) -> JsonObject:
        """{"path": the file, "text": the effective configuration}."""
        return self.call("config")[0]

    def capture(self, *, phases: Optional[int] = None, averages: Optional[int] = None,
                exposure_us: Optional[float] = None, gain_db: Optional[float] = None,
                estimator: Optional[Estimator] = None, dark_frame: Optional[bool] = None,
                verify_phase: Optional[bool] = None, target_error: Optional[float] = None,
                time_budget_ms: Optional[float] = None, speed_px_s: Optional[float] = None,
                save_phases: Optional[bool] = None,
                single_frame: Optional[bool] = None,
                format: Optional[Format] = None, outputs: Optional[Iterable[str]] = None,
                on_progress: Optional[ProgressCallback] = None, timeout: Optional[float] = None) -> Result:
        """Acquires and separates one phase set and returns its Result once it is done. The
        settings are docs/protocol.md's (None: the daemon's configuration); target_error and/or
        time_budget_ms let the daemon choose the rest, and speed_px_s (px/s across the stripes)
        adds to its predictions the motion error of objects moving at it; format "f32" or "u16";
        outputs, e.g. ["transmissive", "scattered", "mask", "max"]; save_phases=True: the raw frames too
        (Result.raw_frames, Result.black). on_progress is called with each phase's
        ProgressEvent. Raises the class of the daemon's error code (BadArgument, Busy,
        DeviceError, Failed, Cancelled), or Timeout after the daemon was told to cancel."""
        args = acquisition_args(phases=phases, averages=averages, exposure_us=exposure_us, gain_db=gain_db,
                                estimator=estimator, dark_frame=dark_frame, verify_phase=verify_phase,
                                target_error=target_error, time_budget_ms=time_budget_ms, speed_px_s=speed_px_s,
                                save_phases=save_phases,
                                single_frame=single_frame)
        if format is not None:
            args["format"] = format
        if outputs is not None:
            args["outputs"] = list(outputs)
        meta, images = self._acquiring_call("capture", timeout=timeout, on_progress=on_progress, progress=True,
                                            **args)
        return Result(meta, images)

    def start(self, *, phases: Optional[int] = None, averages: Optional[int] = None,
              exposure_us: Optional[float] = None, gain_db: Optional[float] = None,
              estimator: Optional[Estimator] = None, dark_frame: Optional[bool] = None,
              verify_phase: Optional[bool] = None, target_error: Optional[float] = None,
              time_budget_ms: Optional[float] = None, speed_px_s: Optional[float] = None,
              save_phases: Optional[bool] = None,
              single_frame: Optional[bool] = None, results: Optional[Results] = None,
              timeout: Optional[float] = None) -> JsonObject:
        """Starts continuous acquisition and returns the settings used; results go to
        subscribers (subscribe()). No settings: the configuration's, following its reloads.
        results="per-frame": a result for every frame from the latest N phases (a sliding
        window; averages must be 1), "per-set": one per phase set. Busy when the daemon
        already acquires."""
        args = acquisition_args(phases=phases, averages=averages, exposure_us=exposure_us, gain_db=gain_db,
                                estimator=estimator, dark_frame=dark_frame, verify_phase=verify_phase,
                                target_error=target_error, time_budget_ms=time_budget_ms, speed_px_s=speed_px_s,
                                save_phases=save_phases,
                                single_frame=single_frame)
        if results is not None:
            args["results"] = results
        return self.call("start", timeout=timeout, **args)[0]

    def stop(self) -> JsonObject:
        """Stops continuous acquisition after the set in progress."""
        return self.call("stop")[0]

    def dark(self, *, averages: Optional[int] = None, exposure_us: Optional[float] = None,
             gain_db: Optional[float] = None, timeout: Optional[float] = None) -> JsonObject:
        """Measures the dark frame (illuminator off); returns {"dark_mean_dn": ...}. Later sets
        with a dark frame subtract it."""
        args = given(averages=averages, exposure_us=exposure_us, gain_db=gain_db)
        return self._acquiring_call("dark", timeout=timeout, **args)[0]

    def set_camera(self, *, exposure_us: Optional[float] = None, gain_db: Optional[float] = None,
                   roi: Optional[Roi] = None, timeout: Optional[float] = None) -> JsonObject:
        """Changes the open camera's exposure (µs), gain (dB) or region (x, y, width, height) between
        two sets (docs/protocol.md, `set`); later captures without their own exposure and gain
        use them. A value outside the camera's range raises descatter.BadArgument naming it and
        the range. Returns the camera's settings as applied: {"exposure_us", "gain_db", "roi":
        {"x", "y", "width", "height"}}."""
        camera: Any = self.call("set", timeout=timeout, **camera_args(exposure_us, gain_db, roi))[0]["camera"]
        return dict(camera)

    def release(self, timeout: Optional[float] = None) -> JsonObject:
        """Closes the daemon's devices so that another program (arv-viewer) can take the
        camera; captures fail with descatter.DeviceError until acquire(). Returns {"state",
        "message"}."""
        return self.call("release", timeout=timeout)[0]

    def acquire(self, timeout: Optional[float] = None) -> JsonObject:
        """Opens the devices again after release(); returns {"state", "message"}."""
        return self.call("acquire", timeout=timeout)[0]

    def calibrate(self, *, phases: Optional[int] = None, averages: Optional[int] = None,
                  exposure_us: Optional[float] = None, gain_db: Optional[float] = None,
                  dark_frame: Optional[bool] = None, period_px: Optional[float] = None,
                  pixel_aperture: Optional[float] = None, timeout: Optional[float] = None) -> JsonObject:
        """One phase set of a reference with little scattering in front of the rig, measured by
        the daemon (descatterctl calibrate); period_px given: known, not measured. Returns a
        dict: period_px, phase_offset_cycles, duty, black_level, harmonic_gain, edge_blur_px,
        ..., set_id and `config`, the descatterd.conf lines that use them (docs/protocol.md).
        Nothing is written to the configuration."""
        args = given(phases=phases, averages=averages, exposure_us=exposure_us, gain_db=gain_db,
                     dark_frame=dark_frame, period_px=period_px, pixel_aperture=pixel_aperture)
        return self._acquiring_call("calibrate", timeout=timeout, **args)[0]

    def cancel(self, timeout: Optional[float] = None) -> JsonObject:
        """Stops what the daemon acquires, whoever asked for it (docs/protocol.md, `cancel`): the
        set in progress ends at its next frame, every capture, calibrate and dark waiting raises
        descatter.Cancelled, continuous acquisition stops. Returns {"cancelled": how many
        requests, "stream_stopped", "state"} once the daemon has stopped. A connection answers
        one request at a time: to cancel a capture another thread waits on, call this on a
        client of its own."""
        return self.call("cancel", timeout=timeout)[0]

    def _acquiring_call(self, cmd: str, timeout: Optional[float] = None,
                        on_progress: Optional[ProgressCallback] = None,
                        **args: Any) -> tuple[JsonObject, dict[str, Image]]:
        """call() for a request that makes the daemon acquire: on a Timeout the daemon is told to
        cancel (on a second connection: this one is still waiting) before the Timeout is raised."""
        try:
            return self.call(cmd, timeout=timeout, on_progress=on_progress, **args)
        except Timeout as exc:
            try:
                with Client(self.address, self.token, timeout=self.timeout) as other:
                    exc.cancel_reply = other.cancel()
            except (OSError, DescatterError) as e:
                exc.cancel_error = e
            raise

    # -- subscription ------------------------------------------------------------------------

    def preview(self, on: bool, light: PreviewLight = "all", phase: Optional[int] = None,
                timeout: Optional[float] = None) -> JsonObject:
        """Free-running frames for aligning the rig (docs/protocol.md, `preview`): on=True starts
        it with light "all" (every stripe lit), "off" (illuminator dark) or "phase" (phase
        `phase` of the configured phases lit); on=False ends it. No phase set is taken and nothing
        is recorded; the frames go to the live view and, with subscribe(frames=True), to this
        client as FrameEvent. Raises descatter.Busy while a capture or continuous acquisition
        runs; a capture, start or dark sent during preview ends it. Returns {"state", "light",
        "phase", "message"}."""
        return self.call("preview", timeout=timeout, **preview_args(on, light, phase))[0]

    def subscribe(self, frames: bool = False) -> "Subscription":
        """Subscribes; returns a Subscription (a context manager that unsubscribes on exit,
        and an iterator of events). frames=True adds preview frames (FrameEvent)."""
        args: JsonObject = {"frames": True} if frames else {}
        result, _ = self.call("subscribe", **args)
        self._subscribed = True
        nxt = result.get("next_seq")
        self._last_seq = nxt - 1 if isinstance(nxt, int) else None
        return Subscription(self)

    def unsubscribe(self) -> JsonObject:
        """Ends the subscription; events not yet read are dropped."""
        self._subscribed = False
        result = self.call("unsubscribe")[0]
        self._events.clear()
        return result


class Subscription:
    """Events of a subscribed client, in order: ResultEvent, FailedEvent, DeviceEvent (and plain
    Event for kinds a newer daemon adds). Each carries `seq` and `lost` (events this client
    missed before it); `lost_total` sums them."""

    def __init__(self, client: Client) -> None:
        self.client = client
        self.lost_total = 0

    def next(self, timeout: Optional[float] = None) -> Event:
        """The next event; waits at most timeout seconds (None: for ever), then raises
        descatter.Timeout with the connection still usable (unless the silence fell in the
        middle of a message: see descatter.Timeout)."""
        c = self.client
        while not c._events:
            if not c._subscribed:
                raise RuntimeError("not subscribed")
            header, images = c.read_message(timeout if timeout is not None else 365 * 86400.0)
            if "event" in header:
                c._queue_event(header, images, None)
        ev = c._events.popleft()
        self.lost_total += ev.lost
        return ev

    def __iter__(self) -> Iterator[Event]:
        while True:
            yield self.next()

    def results(self) -> Iterator[ResultEvent]:
        """Only the results (failed and device events are skipped: use next() to see them)."""
        for ev in self:
            if isinstance(ev, ResultEvent):
                yield ev

    def close(self) -> None:
        """Unsubscribes (when the connection is still open)."""
        if self.client._sock is not None and self.client._subscribed:
            self.client.unsubscribe()

    def __enter__(self) -> "Subscription":
        return self

    def __exit__(self, exc_type: Optional[type[BaseException]], exc: Optional[BaseException],
                 tb: Optional[TracebackType]) -> None:
        self.close()
