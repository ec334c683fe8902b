"""The live view's web server: static page, frames pushed over a WebSocket (aiohttp).

Binds 127.0.0.1 only. Runs its own asyncio loop on a daemon thread, so the
trial's thread only stores the newest frame (:meth:`LiveServer.publish`, a
few microseconds); the server encodes and sends at most ``MAX_RATE_HZ``
updates a second, and only while a page is connected, dropping frames a slow
page cannot take. A page that closes is forgotten; the trial never waits for
it. In replay (``ReplaySource``) the page asks for a frame index and gets that
frame's message and images from the trial's record; its init message also carries
the trial's funnel (``funnel.csv``, docs/RULES.md "The funnel") and the ground-truth
positions (``truth.csv``), which the page lists and draws.
"""

from __future__ import annotations

import asyncio
import base64
import csv
import json
import logging
import math
import threading
from pathlib import Path

import cv2
import numpy as np

from eval.scoring.funnel import CSV_COLUMNS
from poi.core.names import display_name
from poi.core.poi_file import PoiFileError, read_poi_file

STATIC_DIR = Path(__file__).parent / "static"
MAX_RATE_HZ = 10.0
JPEG_QUALITY = 80
# funnel.csv's columns that hold words; the rest are numbers, or empty where they do not apply
FUNNEL_TEXT_COLUMNS = ("kind", "type", "text", "lost_to", "detail")
NO_FUNNEL_NOTE = "no funnel.csv in this trial (written by poibench run since issue 57): no funnel to show"


class LiveError(ValueError):
    """The live view cannot start (one line)."""


def _quiet_bad_requests() -> logging.Logger:
    """The server's error logger, without the tracebacks of requests aiohttp refuses itself.

    A malformed request (an over-long URL or header line, a bad method) is answered by aiohttp
    with 400 and logged with its parser traceback, which lands on the trial's stderr; it is the
    page's mistake, not the server's, so those records are dropped. Errors of the handlers stay.
    """
    from aiohttp.http_exceptions import HttpProcessingError

    log = logging.getLogger("poibench.live.server")

    def keep(record: logging.LogRecord) -> bool:
        exc = record.exc_info[1] if record.exc_info else None
        return not isinstance(exc, HttpProcessingError)

    if not log.filters:
        log.addFilter(keep)
    return log


def _jpeg(rgb: np.ndarray | None) -> str | None:
    if rgb is None:
        return None
    ok, buf = cv2.imencode(".jpg", cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR), [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY])
    return "data:image/jpeg;base64," + base64.b64encode(buf.tobytes()).decode() if ok else None


def _images(camera: np.ndarray | None, insets: np.ndarray | None) -> dict:
    half = None if insets is None else insets.shape[1] // 2
    return {
        "camera": _jpeg(camera),
        "thermal": None if insets is None else _jpeg(np.ascontiguousarray(insets[:, :half])),
        "depth": None if insets is None else _jpeg(np.ascontiguousarray(insets[:, half:])),
    }


def _number(v: str) -> int | float | None:
    if v.strip() == "":
        return None
    f = float(v)
    if not math.isfinite(f):  # JSON has no NaN; the page shows None as a dash
        return None
    return int(f) if f.is_integer() and "." not in v else f


def read_funnel(trial_dir: str | Path) -> dict:
    """The funnel of a trial folder for the page: ``{"rows": [...], "note": str | None}``.

    One row a line of ``funnel.csv`` (its :data:`~eval.scoring.funnel.CSV_COLUMNS`, numbers as
    numbers, empty cells None) with the object's display ``name``; a folder without the file
    (a trial older than the funnel) or with one that cannot be read gives no rows and a note.
    """
    path = Path(trial_dir) / "funnel.csv"
    if not path.exists():
        return {"rows": [], "note": NO_FUNNEL_NOTE}
    try:
        with open(path, newline="", encoding="utf-8") as f:
            rows = []
            for raw in csv.DictReader(f):
                row = {k: (raw.get(k) or "") for k in CSV_COLUMNS}
                row.update({k: _number(v) for k, v in row.items() if k not in FUNNEL_TEXT_COLUMNS})
                row["name"] = display_name(row["type"], row["text"]) if row["type"] else ""
                rows.append(row)
    except (OSError, ValueError, csv.Error) as e:
        return {"rows": [], "note": f"funnel.csv cannot be read ({e}): no funnel to show"}
    return {"rows": rows, "note": None}


def read_truth(trial_dir: str | Path) -> list[dict]:
    """The ground-truth objects of ``truth.csv`` (map frame, m) for the page; [] without one."""
    path = Path(trial_dir) / "truth.csv"
    if not path.exists():
        return []
    try:
        rows = read_poi_file(path).rows
    except PoiFileError:
        return []
    return [
        {
            "id": r.id,
            "type": r.type or "",
            "text": r.text,
            "name": display_name(r.type or "", r.text),
            "x": round(r.x, 3),
            "y": round(r.y, 3),
            "z": round(r.z, 3),
        }
        for r in rows
    ]


def read_frames(path: Path) -> tuple[list[dict], str | None]:
    """The frame messages of a ``frames.jsonl`` up to its first line that is not one, and a
    one-line warning naming that line (None when every line is whole).

    A record cut short (a killed run, a full disk) ends in a torn line; two runs into one
    folder interleave theirs. The replay stops at the first such line: the frames after it
    would no longer match the video's frames by index.
    """
    frames: list[dict] = []
    with open(path, encoding="utf-8", errors="replace") as f:
        for i, line in enumerate(f, 1):
            if not line.strip():
                continue
            try:
                msg = json.loads(line)
            except ValueError:
                msg = None
            if not isinstance(msg, dict) or msg.get("type") != "frame":
                return frames, (
                    f"{path} line {i} is not a whole frame message (a torn or mixed record): "
                    f"replaying the {len(frames)} frames before it"
                )
            frames.append(msg)
    return frames, None


def stopped_record_path(init: dict, frames: list[dict]) -> list | None:
    """The robot's path of a record whose run stopped before its end, rebuilt from its frame
    messages (each frame with a pose added that pose's (x, y) to the path, and says how long the
    path was then, ``path_len``), or None when ``init``'s path is whole. A run's ``init.json`` is
    written as it starts (an empty path) and again at its end."""
    need = max((int(m.get("path_len") or 0) for m in frames), default=0)
    if len(init.get("path") or []) >= need:
        return None
    return [m["pose"][:2] for m in frames if m.get("pose") is not None][:need]


def seek_index(data: str | bytes, n_frames: int) -> int | None:
    """The frame a replay page asks for (``{"seek": K}``), within ``0 .. n_frames - 1``; None
    for a message that is not a seek to a finite number.

    >>> seek_index('{"seek": 12}', 100), seek_index('{"seek": 1e400}', 100), seek_index('{"seek": -3}', 100)
    (12, None, 0)
    >>> seek_index('{"seek": 1' + '0' * 400 + '}', 100), seek_index('[1]', 100), seek_index('{"seek": "2"}', 100)
    (99, None, None)
    """
    try:
        msg = json.loads(data)
    except ValueError:
        return None
    k = msg.get("seek", 0) if isinstance(msg, dict) else None
    if isinstance(k, bool) or not isinstance(k, int | float) or (isinstance(k, float) and not math.isfinite(k)):
        return None  # 1e400 reads as inf: int() of it raised OverflowError in the server
    return int(min(max(k, 0), n_frames - 1))  # compared before int(): a float of 1e308 stays a float


class ReplaySource:
    """A finished trial's record: messages from live/frames.jsonl, images from the videos.

    ``warning``: one line when the record had a torn line (:func:`read_frames`), else None.
    """

    def __init__(self, trial_dir: str | Path) -> None:
        d = Path(trial_dir)
        init_path, frames_path = d / "live" / "init.json", d / "live" / "frames.jsonl"
        if not d.is_dir():
            raise LiveError(f"{d}: no such folder; give a folder written by poibench run")
        if frames_path.exists() and not init_path.exists():
            raise LiveError(
                f"{d}: the live record was never finished (live/frames.jsonl without live/init.json: the trial "
                "was stopped before its end?); rerun the trial"
            )
        if not frames_path.exists() or not init_path.exists():
            raise LiveError(
                f"{d}: no live record (live/init.json, live/frames.jsonl); "
                "run the trial with poibench run, without --no-live-record"
            )
        try:
            self.init = json.loads(init_path.read_text(encoding="utf-8"))
        except ValueError:
            self.init = None
        if not isinstance(self.init, dict):
            raise LiveError(f"{init_path}: not a whole JSON object (a torn record); rerun the trial")
        self.frames, self.warning = read_frames(frames_path)
        if not self.frames:
            raise LiveError(f"{frames_path}: no whole frame message to replay; rerun the trial")
        stopped = stopped_record_path(self.init, self.frames)
        if stopped is not None:
            self.init["path"] = stopped
            last = self.frames[-1].get("k")
            note = f"{d}: the trial stopped at frame {last} before its end: replaying what it recorded"
            self.warning = note if self.warning is None else f"{self.warning}; {note}"
        self.init["n_frames"] = len(self.frames)
        self.init["replay"] = True
        self.init["funnel"] = read_funnel(d)
        self.init["truth"] = read_truth(d)
        self._videos = {}
        for key, name in (("camera", "trial.mp4"), ("insets", "live/insets.mp4")):
            p = d / name
            self._videos[key] = [cv2.VideoCapture(str(p)), -1] if p.exists() else None
        self.init["has_video"] = self._videos["camera"] is not None
        self._lock = threading.Lock()

    def _read(self, key: str, k: int) -> np.ndarray | None:
        entry = self._videos.get(key)
        if entry is None:
            return None
        cap, last = entry
        if k != last + 1:
            cap.set(cv2.CAP_PROP_POS_FRAMES, k)
        ok, bgr = cap.read()
        entry[1] = k if ok else -1
        return cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB) if ok else None

    def frame(self, k: int) -> tuple[dict, dict]:
        k = int(np.clip(k, 0, len(self.frames) - 1))
        with self._lock:
            return self.frames[k], _images(self._read("camera", k), self._read("insets", k))

    def close(self) -> None:
        for entry in self._videos.values():
            if entry is not None:
                entry[0].release()


class LiveServer:
    def __init__(self, port: int = 0, replay: ReplaySource | None = None) -> None:
        if not 0 <= port <= 65535:  # asyncio's bind would raise OverflowError in the server thread
            raise LiveError(f"live view: port {port}: expected 0 to 65535 (0: a free one)")
        self.port = port
        self.replay = replay
        self._init: dict | None = replay.init if replay else None
        self._latest: tuple[dict, np.ndarray | None, np.ndarray | None] | None = None
        self._version = 0
        self._done = False
        self._lock = threading.Lock()
        self._loop: asyncio.AbstractEventLoop | None = None
        self._wake: asyncio.Event | None = None
        self._clients: dict = {}  # websocket -> whether it has had the init message
        self._thread: threading.Thread | None = None
        self._ready = threading.Event()
        self._error: BaseException | None = None
        self.url = ""

    # ------------------------------------------------------------- trial side
    def set_init(self, init: dict) -> None:
        with self._lock:
            self._init = init
        self._poke()  # pages that connected before the trial started get it now

    def publish(self, msg: dict, camera: np.ndarray | None, insets: np.ndarray | None) -> None:
        """Store the newest frame; the server sends it when a page is connected."""
        with self._lock:
            self._latest = (msg, camera, insets)
            self._version += 1
        self._poke()

    def finish(self) -> None:
        self._done = True
        self._poke()

    def _poke(self) -> None:
        if self._loop is not None and self._wake is not None:
            self._loop.call_soon_threadsafe(self._wake.set)

    # ------------------------------------------------------------------ server
    def start(self) -> str:
        self._thread = threading.Thread(target=self._run, name="poibench-live", daemon=True)
        self._thread.start()
        self._ready.wait(30)
        if self._error is not None:
            raise LiveError(f"live view: cannot serve on 127.0.0.1:{self.port} ({self._error})")
        return self.url

    def stop(self) -> None:
        if self._loop is not None:
            self._loop.call_soon_threadsafe(self._loop.stop)
        if self._thread is not None:
            self._thread.join(5)
        if self.replay is not None:
            self.replay.close()

    def _run(self) -> None:
        from aiohttp import web

        loop = asyncio.new_event_loop()
        asyncio.set_event_loop(loop)
        self._loop = loop
        self._wake = asyncio.Event()
        app = web.Application()
        app.router.add_get("/", self._index)
        app.router.add_static("/static/", STATIC_DIR)
        app.router.add_get("/ws", self._ws)
        runner = web.AppRunner(app, access_log=None, logger=_quiet_bad_requests())
        try:
            loop.run_until_complete(runner.setup())
            site = web.TCPSite(runner, "127.0.0.1", self.port)
            loop.run_until_complete(site.start())
            sock = site._server.sockets[0]  # the bound port when 0 was asked for
            self.port = sock.getsockname()[1]
            self.url = f"http://127.0.0.1:{self.port}/"
        except Exception as e:  # noqa: BLE001 (any failure to bind is start()'s one line, never a hang)
            self._error = e
            self._ready.set()
            return
        if self.replay is None:
            loop.create_task(self._broadcast())
        self._ready.set()
        try:
            loop.run_forever()
        finally:
            for task in asyncio.all_tasks(loop):
                task.cancel()
            loop.run_until_complete(asyncio.sleep(0))
            loop.run_until_complete(runner.cleanup())
            loop.close()

    async def _index(self, request):
        from aiohttp import web

        return web.FileResponse(STATIC_DIR / "index.html")

    def _init_message(self) -> dict | None:
        with self._lock:
            if self._init is None:
                return None
            return {**self._init, "path": list(self._init.get("path", [])), "done": self._done}

    async def _ws(self, request):
        from aiohttp import WSMsgType, web

        ws = web.WebSocketResponse(heartbeat=20)
        await ws.prepare(request)
        init = self._init_message()
        await ws.send_str(json.dumps(init if init else {"type": "empty"}))
        if self.replay is not None:
            await self._serve_replay(ws, WSMsgType)
            return ws
        self._clients[ws] = init is not None
        if self._latest is not None:
            self._wake.set()
        try:
            async for _msg in ws:  # a live page only listens; keep the socket open
                pass
        finally:
            self._clients.pop(ws, None)
        return ws

    async def _serve_replay(self, ws, WSMsgType) -> None:
        loop = asyncio.get_running_loop()
        async for m in ws:
            if m.type != WSMsgType.TEXT:
                continue
            k = seek_index(m.data, len(self.replay.frames))
            if k is None:
                continue
            msg, images = await loop.run_in_executor(None, self.replay.frame, k)
            await ws.send_str(json.dumps({**msg, "images": images}))

    async def _broadcast(self) -> None:
        loop = asyncio.get_running_loop()
        sent_version = -1
        while True:
            await self._wake.wait()
            self._wake.clear()
            if not self._clients:
                continue
            with self._lock:
                latest, version = self._latest, self._version
            payloads = []
            if latest is not None and version != sent_version:
                sent_version = version
                msg, camera, insets = latest
                images = await loop.run_in_executor(None, _images, camera, insets)
                payloads.append(json.dumps({**msg, "images": images}))
            if self._done:
                payloads.append(json.dumps({"type": "done"}))
            init = self._init_message()
            for ws, has_init in list(self._clients.items()):
                try:
                    if not has_init:
                        if init is None:
                            continue
                        await asyncio.wait_for(ws.send_str(json.dumps(init)), timeout=2.0)
                        self._clients[ws] = True
                    for p in payloads:
                        await asyncio.wait_for(ws.send_str(p), timeout=2.0)
                except (ConnectionError, asyncio.TimeoutError, RuntimeError):
                    self._clients.pop(ws, None)
            await asyncio.sleep(1.0 / MAX_RATE_HZ)
