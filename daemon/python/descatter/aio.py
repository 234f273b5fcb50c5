"""The asyncio client: the same commands as descatter.Client, as coroutines.

    async with descatter.aio.connect("/run/descatterd/descatterd.sock") as c:
        r = await c.capture(phases=8)
        async with await c.subscribe() as sub:
            async for ev in sub:
                ...

`await connect()` gives the client too (`async with await connect()` keeps working). One task
reads the connection and hands replies to the coroutines waiting for them and events to the
subscription, so several commands may be in flight at once. As with the blocking client,
`timeout` is the silence allowed: a reply awaited while nothing at all arrives for that long
raises descatter.Timeout; the connection stays open and the late reply is dropped.
"""
import asyncio
from collections.abc import Awaitable, Generator, Iterable
from types import TracebackType
from typing import Any, Optional, Union

from . import wire
from ._version import __version__
from .client import (DEFAULT_TIMEOUT, Estimator, Format, PreviewLight, ProgressCallback, Results, Roi, acquisition_args,
                     camera_args, given, preview_args, resolve, split_address)
from .errors import BadReply, DescatterError, Timeout, error_from_reply
from .events import Event, ProgressEvent, Result, make_event, make_frame_event
from .wire import Image, JsonObject

Reply = tuple[JsonObject, dict[str, Image]]


async def _open(address: Optional[str], token: Optional[str], timeout: float) -> "AsyncClient":
    address, token = resolve(address, token)
    _, where = split_address(address)
    limit = wire.MAX_LINE + 2
    if isinstance(where, tuple):
        reader, writer = await asyncio.wait_for(asyncio.open_connection(*where, limit=limit), timeout)
    else:
        reader, writer = await asyncio.wait_for(asyncio.open_unix_connection(where, limit=limit), timeout)
    client = AsyncClient(reader, writer, token, timeout)
    client.address = address
    if token:
        try:
            await client.hello()
        except BaseException:
            await client.close()
            raise
    return client


class Connecting(Awaitable["AsyncClient"]):
    """What connect() returns: await it for the AsyncClient, or use it in `async with`, which
    connects on entry and closes on exit."""

    def __init__(self, address: Optional[str], token: Optional[str], timeout: float) -> None:
        self._args = (address, token, timeout)
        self._client: Optional[AsyncClient] = None

    def __await__(self) -> Generator[Any, None, "AsyncClient"]:
        return _open(*self._args).__await__()

    async def __aenter__(self) -> "AsyncClient":
        self._client = await _open(*self._args)
        return self._client

    async def __aexit__(self, exc_type: Optional[type[BaseException]], exc: Optional[BaseException],
                        tb: Optional[TracebackType]) -> None:
        if self._client is not None:
            await self._client.close()
            self._client = None


def connect(address: Optional[str] = None, token: Optional[str] = None,
            timeout: float = DEFAULT_TIMEOUT) -> Connecting:
    """Connects to descatterd (address and token as descatter.Client; the token is sent in hello
    at once): `async with connect() as c:` or `c = await connect()`. OSError when nobody
    listens, descatter.Unauthorized on a wrong token, asyncio.TimeoutError when connecting
    takes longer than timeout."""
    return Connecting(address, token, timeout)


class AsyncClient:
    """An open connection (from connect()); an async context manager that closes it."""

    def __init__(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter, token: Optional[str],
                 timeout: float) -> None:
        self._reader, self._writer = reader, writer
        self.token, self.timeout = token, timeout
        self.address: Optional[str] = None  # set by connect(): a second connection for cancel
        self._next_id = 0
        self._waiting: dict[int, tuple["asyncio.Future[Reply]", Optional[ProgressCallback]]] = {}
        self._events: asyncio.Queue[Union[Event, BaseException]] = asyncio.Queue()
        self._subscribed = False
        self._last_seq: Optional[int] = None
        self._last_frame_seq: Optional[int] = None
        self._error: Optional[BaseException] = None
        self._last_activity = asyncio.get_running_loop().time()
        self._task = asyncio.get_running_loop().create_task(self._read_loop())

    def __repr__(self) -> str:
        return f"<descatter.aio.AsyncClient {self.address} {'broken' if self._error else 'open'}>"

    async def close(self) -> None:
        """Stops the reader task and closes the connection."""
        self._task.cancel()
        try:
            await self._task
        except (asyncio.CancelledError, Exception):
            pass
        self._writer.close()
        try:
            await self._writer.wait_closed()
        except OSError:
            pass

    async def __aenter__(self) -> "AsyncClient":
        return self

    async def __aexit__(self, exc_type: Optional[type[BaseException]], exc: Optional[BaseException],
                        tb: Optional[TracebackType]) -> None:
        await self.close()

    async def _read_message(self) -> Reply:
        line = await self._reader.readline()
        if not line.endswith(b"\n"):
            raise ConnectionError("descatterd closed the connection")
        header = wire.decode_header(line)
        images: dict[str, Image] = {}
        for name, dtype, shape, nbytes in wire.payload_specs(header):
            array, view = wire.new_array(dtype, shape)
            if nbytes:
                view[:] = await self._reader.readexactly(nbytes)
            images[name] = array
        return header, images

    async def _read_loop(self) -> None:
        try:
            while True:
                header, images = await self._read_message()
                self._last_activity = asyncio.get_running_loop().time()
                if "event" in header:
                    ev: Event
                    if header.get("event") == "frame":
                        ev, self._last_frame_seq = make_frame_event(header, images, self._last_frame_seq)
                    else:
                        ev, self._last_seq = make_event(header, images, self._last_seq)
                    if isinstance(ev, ProgressEvent):
                        waiter = self._waiting.get(ev.body.get("id", -1))
                        if waiter and waiter[1]:
                            waiter[1](ev)
                    elif self._subscribed:
                        self._events.put_nowait(ev)
                    continue
                reply = self._waiting.pop(header.get("id", -1), None)
                if reply and not reply[0].done():
                    reply[0].set_result((header, images))
        except (ConnectionError, BadReply, asyncio.IncompleteReadError, ValueError) as e:
            error = e if isinstance(e, (ConnectionError, BadReply)) else ConnectionError(str(e))
            self._error = error
            for fut, _ in self._waiting.values():
                if not fut.done():
                    fut.set_exception(error)
            self._events.put_nowait(error)

    async def call(self, cmd: str, timeout: Optional[float] = None, on_progress: Optional[ProgressCallback] = None,
                   **args: Any) -> Reply:
        """As descatter.Client.call: (result dict, images), or the exception of the reply's code."""
        if self._error:
            raise self._error
        self._next_id += 1
        rid = self._next_id
        fut: asyncio.Future[Reply] = asyncio.get_running_loop().create_future()
        self._waiting[rid] = (fut, on_progress)
        self._writer.write(wire.encode_request(rid, cmd, args))
        await self._writer.drain()
        limit = self.timeout if timeout is None else timeout
        loop = asyncio.get_running_loop()
        while True:
            try:
                header, images = await asyncio.wait_for(asyncio.shield(fut), limit)
                break
            except asyncio.TimeoutError:
                if loop.time() - self._last_activity < limit:
                    continue  # the line is alive (progress, other traffic): keep waiting
                self._waiting.pop(rid, None)
                raise Timeout(f"{cmd}: nothing from descatterd in {limit:g} s") from None
        if not header.get("ok"):
            raise error_from_reply(header.get("error", {}))
        return header.get("result") or {}, images

    async def hello(self) -> JsonObject:
        """As descatter.Client.hello."""
        args: JsonObject = {"client": f"descatter-python-asyncio/{__version__}"}
        if self.token:
            args["token"] = self.token
        return (await self.call("hello", **args))[0]

    async def status(self) -> JsonObject:
        """As descatter.Client.status."""
        return (await self.call("status"))[0]

    async def config(self) -> JsonObject:
        """As descatter.Client.config."""
        return (await self.call("config"))[0]

    async def capture(self, *, phases: Optional[int] = None, averages: Optional[int] = None,
                      exposure_us: Optional[float] = None, gain_db: Optional[float] = None,
                      estimator: Optional[Estimator] = None, dark_frame: Optional[bool] = None,
                      verify_phase: Optional[bool] = None, target_error: Optional[float] = None,
                      time_budget_ms: Optional[float] = None, speed_px_s: Optional[float] = None,
                      save_phases: Optional[bool] = None,
                      single_frame: Optional[bool] = None,
                      format: Optional[Format] = None, outputs: Optional[Iterable[str]] = None,
                      on_progress: Optional[ProgressCallback] = None, timeout: Optional[float] = None) -> Result:
        """As descatter.Client.capture."""
        args = acquisition_args(phases=phases, averages=averages, exposure_us=exposure_us, gain_db=gain_db,
                                estimator=estimator, dark_frame=dark_frame, verify_phase=verify_phase,
                                target_error=target_error, time_budget_ms=time_budget_ms, speed_px_s=speed_px_s,
                                save_phases=save_phases,
                                single_frame=single_frame)
        if format is not None:
            args["format"] = format
        if outputs is not None:
            args["outputs"] = list(outputs)
        meta, images = await self._acquiring_call("capture", timeout=timeout, on_progress=on_progress,
                                                  progress=True, **args)
        return Result(meta, images)

    async def start(self, *, phases: Optional[int] = None, averages: Optional[int] = None,
                    exposure_us: Optional[float] = None, gain_db: Optional[float] = None,
                    estimator: Optional[Estimator] = None, dark_frame: Optional[bool] = None,
                    verify_phase: Optional[bool] = None, target_error: Optional[float] = None,
                    time_budget_ms: Optional[float] = None, speed_px_s: Optional[float] = None,
                    save_phases: Optional[bool] = None,
                    single_frame: Optional[bool] = None, results: Optional[Results] = None,
                    timeout: Optional[float] = None) -> JsonObject:
        """As descatter.Client.start."""
        args = acquisition_args(phases=phases, averages=averages, exposure_us=exposure_us, gain_db=gain_db,
                                estimator=estimator, dark_frame=dark_frame, verify_phase=verify_phase,
                                target_error=target_error, time_budget_ms=time_budget_ms, speed_px_s=speed_px_s,
                                save_phases=save_phases,
                                single_frame=single_frame)
        if results is not None:
            args["results"] = results
        return (await self.call("start", timeout=timeout, **args))[0]

    async def stop(self) -> JsonObject:
        """As descatter.Client.stop."""
        return (await self.call("stop"))[0]

    async def dark(self, *, averages: Optional[int] = None, exposure_us: Optional[float] = None,
                   gain_db: Optional[float] = None, timeout: Optional[float] = None) -> JsonObject:
        """As descatter.Client.dark."""
        args = given(averages=averages, exposure_us=exposure_us, gain_db=gain_db)
        return (await self._acquiring_call("dark", timeout=timeout, **args))[0]

    async def set_camera(self, *, exposure_us: Optional[float] = None, gain_db: Optional[float] = None,
                         roi: Optional[Roi] = None, timeout: Optional[float] = None) -> JsonObject:
        """As descatter.Client.set_camera."""
        camera: Any = (await self.call("set", timeout=timeout, **camera_args(exposure_us, gain_db, roi)))[0]["camera"]
        return dict(camera)

    async def release(self, timeout: Optional[float] = None) -> JsonObject:
        """As descatter.Client.release."""
        return (await self.call("release", timeout=timeout))[0]

    async def acquire(self, timeout: Optional[float] = None) -> JsonObject:
        """As descatter.Client.acquire."""
        return (await self.call("acquire", timeout=timeout))[0]

    async def calibrate(self, *, phases: Optional[int] = None, averages: Optional[int] = None,
                        exposure_us: Optional[float] = None, gain_db: Optional[float] = None,
                        dark_frame: Optional[bool] = None, period_px: Optional[float] = None,
                        pixel_aperture: Optional[float] = None, timeout: Optional[float] = None) -> JsonObject:
        """As descatter.Client.calibrate."""
        args = given(phases=phases, averages=averages, exposure_us=exposure_us, gain_db=gain_db,
                     dark_frame=dark_frame, period_px=period_px, pixel_aperture=pixel_aperture)
        return (await self._acquiring_call("calibrate", timeout=timeout, **args))[0]

    async def cancel(self, timeout: Optional[float] = None) -> JsonObject:
        """As descatter.Client.cancel (the request waiting on this connection is answered first:
        cancel another task's capture from a client of its own)."""
        return (await self.call("cancel", timeout=timeout))[0]

    async def _acquiring_call(self, cmd: str, timeout: Optional[float] = None,
                              on_progress: Optional[ProgressCallback] = None, **args: Any) -> Reply:
        """As descatter.Client: a Timeout cancels the daemon's acquisition before it is raised."""
        try:
            return await self.call(cmd, timeout=timeout, on_progress=on_progress, **args)
        except Timeout as exc:
            try:
                other = await connect(self.address, self.token, self.timeout)
                try:
                    exc.cancel_reply = await other.cancel()
                finally:
                    await other.close()
            except (OSError, DescatterError, asyncio.TimeoutError) as e:
                exc.cancel_error = e
            raise

    async def preview(self, on: bool, light: PreviewLight = "all", phase: Optional[int] = None,
                      timeout: Optional[float] = None) -> JsonObject:
        """As descatter.Client.preview."""
        return (await self.call("preview", timeout=timeout, **preview_args(on, light, phase)))[0]

    async def subscribe(self, frames: bool = False) -> "AsyncSubscription":
        """Subscribes; returns an AsyncSubscription (`async for`, `async with`). frames=True adds
        preview frames (FrameEvent)."""
        self._subscribed = True  # before the reply: events may follow it at once
        try:
            args: JsonObject = {"frames": True} if frames else {}
            result, _ = await self.call("subscribe", **args)
        except BaseException:
            self._subscribed = False
            raise
        nxt = result.get("next_seq")
        if isinstance(nxt, int):
            self._last_seq = nxt - 1
        return AsyncSubscription(self)

    async def unsubscribe(self) -> JsonObject:
        """As descatter.Client.unsubscribe."""
        self._subscribed = False
        result = (await self.call("unsubscribe"))[0]
        while not self._events.empty():
            self._events.get_nowait()
        return result


class AsyncSubscription:
    """As descatter.Subscription, for `async for` and `async with`."""

    def __init__(self, client: AsyncClient) -> None:
        self.client = client
        self.lost_total = 0

    async def next(self, timeout: Optional[float] = None) -> Event:
        """The next event; waits at most timeout seconds (None: for ever), then raises
        descatter.Timeout with the subscription still usable."""
        try:
            ev = await asyncio.wait_for(self.client._events.get(), timeout)
        except asyncio.TimeoutError:
            raise Timeout(f"no event in {timeout:g} s") from None
        if isinstance(ev, BaseException):
            self.client._events.put_nowait(ev)  # every later call sees it too
            raise ev
        self.lost_total += ev.lost
        return ev

    def __aiter__(self) -> "AsyncSubscription":
        return self

    async def __anext__(self) -> Event:
        return await self.next()

    async def close(self) -> None:
        """Unsubscribes (unless the connection broke)."""
        if self.client._subscribed and not self.client._error:
            await self.client.unsubscribe()

    async def __aenter__(self) -> "AsyncSubscription":
        return self

    async def __aexit__(self, exc_type: Optional[type[BaseException]], exc: Optional[BaseException],
                        tb: Optional[TracebackType]) -> None:
        await self.close()
