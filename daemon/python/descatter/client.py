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
"""
import collections
import os
import select
import socket

from . import wire
from ._version import __version__
from .errors import BadReply, DescatterError, Timeout, error_from_reply
from .events import ProgressEvent, Result, make_event, make_frame_event

DEFAULT_ADDRESS = "/run/descatterd/descatterd.sock"
DEFAULT_TIMEOUT = 60.0
_ACQ_KEYS = ("phases", "averages", "exposure_us", "gain_db", "estimator", "dark_frame", "verify_phase",
             "target_error", "time_budget_ms", "save_phases")


def resolve(address, token):
    """The address and token in use: given, else $DESCATTER_ADDRESS / $DESCATTER_TOKEN (as for
    descatterctl), else the default socket and no token."""
    address = address or os.environ.get("DESCATTER_ADDRESS") or DEFAULT_ADDRESS
    if token is None:
        token = os.environ.get("DESCATTER_TOKEN") or None
    return address, token


def split_address(address):
    """("tcp", (host, port)) or ("unix", path) for "tcp:HOST:PORT", "unix:PATH" or a path."""
    if address.startswith("tcp:"):
        host, sep, port = address[4:].rpartition(":")
        if not sep or not host or not port.isdigit() or not 0 < int(port) < 65536:
            raise ValueError(f"address {address!r}: expected tcp:HOST:PORT")
        return "tcp", (host.strip("[]"), int(port))
    return "unix", address[5:] if address.startswith("unix:") else address


def acquisition_args(kwargs, allowed):
    """The arguments given (None = not given: the daemon's configuration decides)."""
    unknown = set(kwargs) - set(allowed)
    if unknown:
        raise TypeError(f"unknown argument(s): {', '.join(sorted(unknown))}")
    return {k: v for k, v in kwargs.items() if v is not None}


_CALIBRATE_KEYS = ("phases", "averages", "exposure_us", "gain_db", "dark_frame", "period_px", "pixel_aperture")


class Client:
    def __init__(self, address=None, token=None, timeout=DEFAULT_TIMEOUT):
        """address: a UNIX socket path, "unix:PATH" or "tcp:HOST:PORT"; token: the daemon's TCP
        token (sent in hello at once); timeout: seconds of silence allowed while waiting."""
        self.address, self.token = resolve(address, token)
        self.timeout = timeout
        kind, where = split_address(self.address)
        if kind == "tcp":
            self._sock = socket.create_connection(where, timeout=timeout)
        else:
            self._sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
            self._sock.settimeout(timeout)
            try:
                self._sock.connect(where)
            except OSError:
                self._sock.close()
                raise
        self._sock.setblocking(True)
        self._sock.settimeout(None)
        self._buf = bytearray()
        self._next_id = 0
        self._events = collections.deque()  # events read while waiting for a reply
        self._subscribed = False
        self._last_seq = None
        self._last_frame_seq = None
        self._broken = None
        if self.token:
            try:
                self.hello()
            except BaseException:
                self.close()
                raise

    # -- connection --------------------------------------------------------------------------

    def close(self):
        if self._sock is not None:
            self._sock.close()
            self._sock = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def _fail(self, exc):
        """The stream is out of sync: nothing more can be read from this connection."""
        self._broken = str(exc)
        self.close()
        raise exc

    def _fill(self, timeout, mid_message):
        if self._sock is None:
            raise ConnectionError(f"connection closed ({self._broken or 'closed by the caller'})")
        ready, _, _ = select.select([self._sock], [], [], timeout)
        if not ready:
            exc = Timeout(f"no message from descatterd in {timeout:g} s")
            if mid_message:
                self._fail(exc)
            raise exc
        chunk = self._sock.recv(1 << 20)
        if not chunk:
            self._fail(ConnectionError("descatterd closed the connection"))
        self._buf += chunk

    def _read_line(self, timeout):
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

    def _read_into(self, view, timeout):
        n = min(len(view), len(self._buf))
        view[:n] = self._buf[:n]
        del self._buf[:n]
        while n < len(view):
            ready, _, _ = select.select([self._sock], [], [], timeout)
            if not ready:
                self._fail(Timeout(f"payload stalled for {timeout:g} s"))
            got = self._sock.recv_into(view[n:])
            if got == 0:
                self._fail(ConnectionError("descatterd closed the connection mid-payload"))
            n += got

    def read_message(self, timeout=None):
        """The next message as (header dict, {payload name: writable numpy array}). timeout:
        seconds to wait for it (None: the client's); a timeout before the message started
        leaves the connection usable."""
        timeout = self.timeout if timeout is None else timeout
        try:
            header = wire.decode_header(self._read_line(timeout))
            images = {}
            for name, dtype, shape, nbytes in wire.payload_specs(header):
                array, view = wire.new_array(dtype, shape)
                if nbytes:
                    self._read_into(view, timeout)
                images[name] = array
            return header, images
        except BadReply as e:
            self._fail(e)

    # -- requests ----------------------------------------------------------------------------

    def _queue_event(self, header, images, on_progress):
        if header.get("event") == "frame":
            ev, self._last_frame_seq = make_frame_event(header, images, self._last_frame_seq)
        else:
            ev, self._last_seq = make_event(header, images, self._last_seq)
        if isinstance(ev, ProgressEvent):
            if on_progress:
                on_progress(ev)
        elif self._subscribed:
            self._events.append(ev)

    def call(self, cmd, timeout=None, on_progress=None, **args):
        """Sends a command and returns (result dict, images). A reply with ok=false raises the
        exception of its code (descatter.BadArgument, descatter.Busy, ...). Events that arrive
        meanwhile are kept for the subscription (progress events go to on_progress)."""
        self._next_id += 1
        rid = self._next_id
        if self._sock is None:
            raise ConnectionError(f"connection closed ({self._broken or 'closed by the caller'})")
        self._sock.sendall(wire.encode_request(rid, cmd, args))
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

    def hello(self):
        args = {"client": f"descatter-python/{__version__}"}
        if self.token:
            args["token"] = self.token
        return self.call("hello", **args)[0]

    def status(self):
        return self.call("status")[0]

    def config(self):
        """{"path": the file, "text": the effective configuration}."""
        return self.call("config")[0]

    def capture(self, *, format=None, outputs=None, on_progress=None, timeout=None, **settings):
        """One phase set: phases, averages, exposure_us, gain_db, estimator, dark_frame,
        verify_phase, target_error, time_budget_ms (None or absent: the configuration's);
        format "f32"/"u16"; outputs, e.g. ["transmissive", "scattered", "mask", "max"];
        save_phases=True: the raw frames too (Result.raw_frames, Result.black)."""
        args = acquisition_args(settings, _ACQ_KEYS)
        if format is not None:
            args["format"] = format
        if outputs is not None:
            args["outputs"] = list(outputs)
        meta, images = self._acquiring_call("capture", timeout=timeout, on_progress=on_progress, progress=True,
                                            **args)
        return Result(meta, images)

    def start(self, **settings):
        """Continuous acquisition (results go to subscribers); no settings: the configuration's,
        following its reloads. Returns the settings used."""
        return self.call("start", **acquisition_args(settings, _ACQ_KEYS))[0]

    def stop(self):
        return self.call("stop")[0]

    def dark(self, *, averages=None, exposure_us=None, gain_db=None, timeout=None):
        """Measures the dark frame; returns {"dark_mean_dn": ...}."""
        args = acquisition_args(dict(averages=averages, exposure_us=exposure_us, gain_db=gain_db),
                                ("averages", "exposure_us", "gain_db"))
        return self._acquiring_call("dark", timeout=timeout, **args)[0]

    def release(self, timeout=None):
        """Closes the daemon's devices so that another program (arv-viewer) can take the
        camera; captures fail with descatter.DeviceError until acquire(). Returns {"state",
        "message"}."""
        return self.call("release", timeout=timeout)[0]

    def acquire(self, timeout=None):
        """Opens the devices again after release(); returns {"state", "message"}."""
        return self.call("acquire", timeout=timeout)[0]

    def calibrate(self, *, timeout=None, **settings):
        """One phase set of a reference with little scattering in front of the rig, measured by
        the daemon (descatterctl calibrate): phases, averages, exposure_us, gain_db, dark_frame,
        period_px (known: not measured), pixel_aperture. Returns a dict: period_px,
        phase_offset_cycles, duty, black_level, harmonic_gain, edge_blur_px, ..., set_id and
        `config`, the descatterd.conf lines that use them (docs/protocol.md)."""
        args = acquisition_args(settings, _CALIBRATE_KEYS)
        return self._acquiring_call("calibrate", timeout=timeout, **args)[0]

    def cancel(self, timeout=None):
        """Stops what the daemon acquires, whoever asked for it (docs/protocol.md, `cancel`): the
        set in progress ends at its next frame, every capture, calibrate and dark waiting raises
        descatter.Cancelled, continuous acquisition stops. Returns {"cancelled": how many
        requests, "stream_stopped", "state"} once the daemon has stopped. A connection answers
        one request at a time: to cancel a capture another thread waits on, call this on a
        client of its own."""
        return self.call("cancel", timeout=timeout)[0]

    def _acquiring_call(self, cmd, **kw):
        """call() for a request that makes the daemon acquire: on a Timeout the daemon is told to
        cancel (on a second connection: this one is still waiting) before the Timeout is raised."""
        try:
            return self.call(cmd, **kw)
        except Timeout as exc:
            try:
                with Client(self.address, self.token, timeout=self.timeout) as other:
                    exc.cancel_reply = other.cancel()
            except (OSError, DescatterError) as e:
                exc.cancel_error = e
            raise

    # -- subscription ------------------------------------------------------------------------

    def preview(self, on, light="all", phase=None, timeout=None):
        """Free-running frames for aligning the rig (docs/protocol.md, `preview`): on=True starts
        it with light "all" (every stripe lit), "off" (illuminator dark) or "phase" (phase
        `phase` of the configured phases lit); on=False ends it. No phase set is taken and nothing
        is recorded; the frames go to the live view and, with subscribe(frames=True), to this
        client as FrameEvent. Raises descatter.Busy while a capture or continuous acquisition
        runs; a capture, start or dark sent during preview ends it. Returns {"state", "light",
        "phase", "message"}."""
        if not on:
            return self.call("preview", timeout=timeout, state="off")[0]
        args = {"state": "on", "light": light}
        if phase is not None:
            args["phase"] = phase
        return self.call("preview", timeout=timeout, **args)[0]

    def subscribe(self, frames=False):
        """Subscribes; returns a Subscription (a context manager that unsubscribes on exit,
        and an iterator of events). frames=True adds preview frames (FrameEvent)."""
        result, _ = self.call("subscribe", **({"frames": True} if frames else {}))
        self._subscribed = True
        nxt = result.get("next_seq")
        self._last_seq = nxt - 1 if isinstance(nxt, int) else None
        return Subscription(self)

    def unsubscribe(self):
        self._subscribed = False
        result = self.call("unsubscribe")[0]
        self._events.clear()
        return result


class Subscription:
    """Events of a subscribed client, in order: ResultEvent, FailedEvent, DeviceEvent (and plain
    Event for kinds a newer daemon adds). Each carries `seq` and `lost` (events this client
    missed before it); `lost_total` sums them."""

    def __init__(self, client):
        self.client = client
        self.lost_total = 0

    def next(self, timeout=None):
        """The next event; waits at most timeout seconds (None: for ever), then raises
        descatter.Timeout with the connection still usable."""
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

    def __iter__(self):
        while True:
            yield self.next()

    def results(self):
        """Only the results (failed and device events are skipped: use next() to see them)."""
        for ev in self:
            if ev.kind == "result":
                yield ev

    def close(self):
        if self.client._sock is not None and self.client._subscribed:
            self.client.unsubscribe()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
