"""The asyncio client: the same commands as descatter.Client, as coroutines.

    async with await descatter.aio.connect("/run/descatterd/descatterd.sock") as c:
        r = await c.capture(phases=8)
        async with await c.subscribe() as sub:
            async for ev in sub:
                ...

One task reads the connection and hands replies to the coroutines waiting for them and events
to the subscription, so several commands may be in flight at once. As with the blocking
client, `timeout` is the silence allowed: a reply awaited while nothing at all arrives for
that long raises descatter.Timeout.
"""
import asyncio

from . import wire
from ._version import __version__
from .client import _ACQ_KEYS, _CALIBRATE_KEYS, DEFAULT_TIMEOUT, acquisition_args, resolve, split_address
from .errors import BadReply, DescatterError, Timeout, error_from_reply
from .events import ProgressEvent, Result, make_event, make_frame_event


async def connect(address=None, token=None, timeout=DEFAULT_TIMEOUT):
    """Connects (and sends the token in hello when there is one)."""
    address, token = resolve(address, token)
    kind, where = split_address(address)
    if kind == "tcp":
        reader, writer = await asyncio.wait_for(asyncio.open_connection(*where, limit=wire.MAX_LINE + 2), timeout)
    else:
        reader, writer = await asyncio.wait_for(asyncio.open_unix_connection(where, limit=wire.MAX_LINE + 2), timeout)
    client = AsyncClient(reader, writer, token, timeout)
    client.address = address
    if token:
        try:
            await client.hello()
        except BaseException:
            await client.close()
            raise
    return client


class AsyncClient:
    def __init__(self, reader, writer, token, timeout):
        self._reader, self._writer = reader, writer
        self.token, self.timeout = token, timeout
        self.address = None  # set by connect(): a second connection for cancel
        self._next_id = 0
        self._waiting = {}  # request id -> (future, on_progress)
        self._events = asyncio.Queue()
        self._subscribed = False
        self._last_seq = None
        self._last_frame_seq = None
        self._error = None
        self._last_activity = asyncio.get_running_loop().time()
        self._task = asyncio.get_running_loop().create_task(self._read_loop())

    async def close(self):
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

    async def __aenter__(self):
        return self

    async def __aexit__(self, *exc):
        await self.close()

    async def _read_message(self):
        line = await self._reader.readline()
        if not line.endswith(b"\n"):
            raise ConnectionError("descatterd closed the connection")
        header = wire.decode_header(line)
        images = {}
        for name, dtype, shape, nbytes in wire.payload_specs(header):
            array, view = wire.new_array(dtype, shape)
            if nbytes:
                view[:] = await self._reader.readexactly(nbytes)
            images[name] = array
        return header, images

    async def _read_loop(self):
        try:
            while True:
                header, images = await self._read_message()
                self._last_activity = asyncio.get_running_loop().time()
                if "event" in header:
                    if header.get("event") == "frame":
                        ev, self._last_frame_seq = make_frame_event(header, images, self._last_frame_seq)
                    else:
                        ev, self._last_seq = make_event(header, images, self._last_seq)
                    if isinstance(ev, ProgressEvent):
                        waiter = self._waiting.get(ev.body.get("id"))
                        if waiter and waiter[1]:
                            waiter[1](ev)
                    elif self._subscribed:
                        self._events.put_nowait(ev)
                    continue
                waiter = self._waiting.pop(header.get("id"), None)
                if waiter and not waiter[0].done():
                    waiter[0].set_result((header, images))
        except (ConnectionError, BadReply, asyncio.IncompleteReadError, ValueError) as e:
            self._error = e if isinstance(e, (ConnectionError, BadReply)) else ConnectionError(str(e))
            for fut, _ in self._waiting.values():
                if not fut.done():
                    fut.set_exception(self._error)
            self._events.put_nowait(self._error)

    async def call(self, cmd, timeout=None, on_progress=None, **args):
        """As descatter.Client.call: (result dict, images), or the exception of the reply's code."""
        if self._error:
            raise self._error
        self._next_id += 1
        rid = self._next_id
        fut = asyncio.get_running_loop().create_future()
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

    async def hello(self):
        args = {"client": f"descatter-python-asyncio/{__version__}"}
        if self.token:
            args["token"] = self.token
        return (await self.call("hello", **args))[0]

    async def status(self):
        return (await self.call("status"))[0]

    async def config(self):
        return (await self.call("config"))[0]

    async def capture(self, *, format=None, outputs=None, on_progress=None, timeout=None, **settings):
        """As descatter.Client.capture."""
        args = acquisition_args(settings, _ACQ_KEYS)
        if format is not None:
            args["format"] = format
        if outputs is not None:
            args["outputs"] = list(outputs)
        meta, images = await self._acquiring_call("capture", timeout=timeout, on_progress=on_progress,
                                                  progress=True, **args)
        return Result(meta, images)

    async def start(self, **settings):
        return (await self.call("start", **acquisition_args(settings, _ACQ_KEYS)))[0]

    async def stop(self):
        return (await self.call("stop"))[0]

    async def dark(self, *, averages=None, exposure_us=None, gain_db=None, timeout=None):
        args = acquisition_args(dict(averages=averages, exposure_us=exposure_us, gain_db=gain_db),
                                ("averages", "exposure_us", "gain_db"))
        return (await self._acquiring_call("dark", timeout=timeout, **args))[0]

    async def release(self, timeout=None):
        return (await self.call("release", timeout=timeout))[0]

    async def acquire(self, timeout=None):
        return (await self.call("acquire", timeout=timeout))[0]

    async def calibrate(self, *, timeout=None, **settings):
        args = acquisition_args(settings, _CALIBRATE_KEYS)
        return (await self._acquiring_call("calibrate", timeout=timeout, **args))[0]

    async def cancel(self, timeout=None):
        """As descatter.Client.cancel (the request waiting on this connection is answered first:
        cancel another task's capture from a client of its own)."""
        return (await self.call("cancel", timeout=timeout))[0]

    async def _acquiring_call(self, cmd, **kw):
        """As descatter.Client: a Timeout cancels the daemon's acquisition before it is raised."""
        try:
            return await self.call(cmd, **kw)
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

    async def preview(self, on, light="all", phase=None, timeout=None):
        """As Client.preview."""
        if not on:
            return (await self.call("preview", timeout=timeout, state="off"))[0]
        args = {"state": "on", "light": light}
        if phase is not None:
            args["phase"] = phase
        return (await self.call("preview", timeout=timeout, **args))[0]

    async def subscribe(self, frames=False):
        self._subscribed = True  # before the reply: events may follow it at once
        try:
            result, _ = await self.call("subscribe", **({"frames": True} if frames else {}))
        except BaseException:
            self._subscribed = False
            raise
        nxt = result.get("next_seq")
        if isinstance(nxt, int):
            self._last_seq = nxt - 1
        return AsyncSubscription(self)

    async def unsubscribe(self):
        self._subscribed = False
        result = (await self.call("unsubscribe"))[0]
        while not self._events.empty():
            self._events.get_nowait()
        return result


class AsyncSubscription:
    """As descatter.Subscription, for `async for` and `async with`."""

    def __init__(self, client):
        self.client = client
        self.lost_total = 0

    async def next(self, timeout=None):
        try:
            ev = await asyncio.wait_for(self.client._events.get(), timeout)
        except asyncio.TimeoutError:
            raise Timeout(f"no event in {timeout:g} s") from None
        if isinstance(ev, Exception):
            self.client._events.put_nowait(ev)  # every later call sees it too
            raise ev
        self.lost_total += ev.lost
        return ev

    def __aiter__(self):
        return self

    async def __anext__(self):
        return await self.next()

    async def close(self):
        if self.client._subscribed and not self.client._error:
            await self.client.unsubscribe()

    async def __aenter__(self):
        return self

    async def __aexit__(self, *exc):
        await self.close()
