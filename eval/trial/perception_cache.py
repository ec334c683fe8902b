"""The perception cache: a trial's perception recorded once and replayed for every downstream setting.

A sweep or a tuning study runs the same scenarios again and again with settings that only
the stages after detection read (``tracker.*``, ``slam.*``, ``localize.*``, ``visibility.*``,
``detector.conf`` and ``detector.type_conf`` at or above :data:`CONF_FLOOR`, ``calibration``).
Rendering and detection, about 90% of a trial's CPU, give the same result each time, so they
run once per scenario:
:func:`eval.trial.sources.record_perception` runs the simulator and the detectors and keeps, per
frame, what the pipeline after detection reads (:class:`FrameRecord`):

* the detections of every detector, the ONNX detector's down to :data:`CONF_FLOOR`;
* the depth image, exact, in zlib-compressed 32 x 32 tiles of its Z16 counts (:class:`TiledDepth`):
  localisation reads each box's crop and the pixels round its centre, the in-view test
  one pixel per track, so a replay decompresses a few tiles a frame;
* the pose (and the true pose, for the pose error of ``score.json``);
* the text the QR reader gives every QR box that has none (``attach_qr_text`` reads
  each box on its own, so a replay asks for any subset of them).

A replay (:meth:`PerceptionRecord.frames`, :class:`ReplayDetector`,
:meth:`PerceptionRecord.qr_reader`) feeds those inputs to the same
:class:`poi.pipeline.Pipeline`; ``run_trial`` writes the same ``pois.csv`` and
``score.json`` as a trial that renders every frame (tests/eval/trial/test_perception_cache.py).

Records are keyed (:func:`perception_key`) by everything that changes them: the scenario
(its YAML: seed, sensors, robot, maze), the detector choice and the SHA-256 of its model
files, the detector settings other than ``conf`` and ``type_conf``, ``thermal.*``, the frame count, the
floor, the versions of the libraries that render and detect and the OpenGL renderer's
(:func:`sim.gl.renderer_identity`: another Mesa draws other pixels), and a hash of the source
that simulates and detects (so a code change never replays an old record). A record is
one file, written to a temporary name and renamed over the final one (``os.replace``,
atomic on POSIX and Windows), so parallel workers and Ray tasks never read a half-written
one; its header holds a format number, the payload length and its CRC-32, and a record
whose header, length, checksum or key does not match is recomputed, never trusted.

Records are Python pickles: the cache folder is trusted like the user's own files, as
joblib's ``Memory`` trusts its cache.
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import hashlib
import json
import math
import os
import pickle
import struct
import time
import zlib
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from eval.scoring.funnel import ObjectView
from poi.core.atomic_file import atomic_path
from poi.core.depth_units import from_z16, to_z16
from poi.core.types import Detection, Frame, Intrinsics

# 2: detections carry class_probs over 29 classes (landolt-c added); 3: drift_multiplier;
# 4: frames carry pose_relocalised; 5: frames carry the truth's object views and the blur (the funnel);
# 6: depth tiles of Z16 counts (TiledDepth.unit_m)
CACHE_FORMAT = 6
CONF_FLOOR = 0.05  # ONNX detections are recorded down to this score; detector.conf below it runs in full
TILE_PX = 32
MAGIC = b"POIBPCR\x00"
HEADER = struct.Struct("<8sIQI")  # magic, format, payload length, CRC-32 of the payload
SUFFIX = ".pcache"
STALE_TEMP_S = 3600.0  # a temporary file this old was left by a killed writer
# The folder's size limit (PerceptionCache): about a hundred 40-s recordings, ten suites' worth
DEFAULT_MAX_GB = 20.0
MAX_GB_ENV = "POIBENCH_CACHE_MAX_GB"
EMPTY_RGB = np.zeros((0, 0, 3), np.uint8)  # a replayed frame has no pixels; nothing after detection reads them
ONNX_SOURCE = "onnx"  # Detection.source of the ONNX detector, the one detector.conf filters
ROOT = Path(__file__).resolve().parents[2]
# the source that simulates and detects: a change in any of it makes every record stale
FINGERPRINT_DIRS = ("sim", "maze_assets", "poi/detectors", "poi/core")
FINGERPRINT_FILES = (
    "eval/trial/perception_cache.py",
    "eval/trial/sources.py",
    "eval/trial/detectors.py",
    "eval/trial/episode.py",
    "eval/scoring/truth.py",
    "eval/scoring/funnel.py",
)


class PerceptionCacheError(ValueError):
    """A cache folder that cannot be used (one line)."""


def default_cache_dir() -> Path:
    """``$XDG_CACHE_HOME/poibench/perception``, or ``~/.cache/poibench/perception``."""
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "poibench" / "perception"


# ------------------------------------------------------------------------------ depth


@dataclass(frozen=True)
class TiledDepth:
    """A depth image kept as zlib-compressed ``tile`` x ``tile`` tiles, read like an ndarray.

    Supports what the pipeline does with ``Frame.depth_m``: ``.shape``, ``.dtype``,
    ``d[row, col]`` (a scalar of the image's dtype), ``d[r0:r1, c0:c1]`` (a new array) and
    ``np.asarray(d)`` (the whole image); only the tiles read are decompressed. Values are exact.

    With ``unit_m``, a float32 image on the Z16 grid (the simulator's depth is, poi.core.depth_units)
    is kept as its uint16 counts, each tile's high bytes before its low ones: the high bytes of
    neighbouring depths repeat and compress well, the low ones hold the noise. Decoded with
    :func:`poi.core.depth_units.from_z16` it is the image bit for bit (checked when it is made; an
    image off the grid is kept as it is). On a trial's 640x480 frames: 175 KB a frame against 273
    for the float32 tiles.

    >>> a = np.arange(70 * 50, dtype=np.float32).reshape(70, 50)
    >>> t = TiledDepth.from_array(a, tile=32)
    >>> t.shape, float(t[69, 49]), bool(np.array_equal(t[30:40, 5:45], a[30:40, 5:45]))
    ((70, 50), 3499.0, True)
    >>> bool(np.array_equal(np.asarray(t, dtype=np.float64), a))
    True
    >>> z = from_z16(np.arange(70 * 50, dtype=np.uint16).reshape(70, 50))  # 0 to 3.499 m, 1 mm counts
    >>> t = TiledDepth.from_array(z, tile=32, unit_m=0.001)
    >>> t.unit_m, t.dtype, bool(np.array_equal(t[:, :], z)), bool(t[69, 49] == z[69, 49])
    (0.001, '<f4', True, True)
    >>> TiledDepth.from_array(z + np.float32(1e-4), unit_m=0.001).unit_m is None  # off the grid
    True
    """

    shape: tuple[int, int]
    dtype: str
    tile: int
    blob: bytes
    offsets: np.ndarray  # (n_tiles + 1,) start of each compressed tile in blob, row-major tiles
    unit_m: float | None = None  # the tiles hold Z16 counts of this unit (high bytes, then low)
    _decoded: dict = field(default_factory=dict, compare=False, repr=False)

    @classmethod
    def from_array(cls, a: np.ndarray, tile: int = TILE_PX, unit_m: float | None = None) -> TiledDepth:
        if a.ndim != 2:
            raise ValueError(f"depth: expected an (H, W) image, got shape {a.shape}")
        src = a
        if unit_m is not None:
            counts = to_z16(a, unit_m) if a.dtype == np.float32 else None
            if counts is not None and np.array_equal(from_z16(counts, unit_m).view(np.uint32), a.view(np.uint32)):
                src = counts
            else:
                unit_m = None
        H, W = a.shape
        parts, offsets = [], [0]
        for r in range(0, H, tile):
            for c in range(0, W, tile):
                part = np.ascontiguousarray(src[r : r + tile, c : c + tile])
                data = _split_bytes(part) if unit_m is not None else part.tobytes()
                z = zlib.compress(data, 1)
                parts.append(z)
                offsets.append(offsets[-1] + len(z))
        return cls(
            shape=(H, W),
            dtype=a.dtype.str,
            tile=tile,
            blob=b"".join(parts),
            offsets=np.asarray(offsets, np.int64),
            unit_m=unit_m,
        )

    def __getstate__(self) -> dict:
        return {k: getattr(self, k) for k in ("shape", "dtype", "tile", "blob", "offsets", "unit_m")}

    def __setstate__(self, state: dict) -> None:
        for k, v in state.items():
            object.__setattr__(self, k, v)
        object.__setattr__(self, "_decoded", {})

    @property
    def ndim(self) -> int:
        return 2

    def __array__(self, dtype=None, copy=None) -> np.ndarray:
        """The whole image (the fiducial mapper reads all of it, subsampled)."""
        a = self[:, :]
        return a if dtype is None else a.astype(dtype)

    def _tile(self, i: int, j: int) -> np.ndarray:
        got = self._decoded.get((i, j))
        if got is None:
            H, W = self.shape
            t = self.tile
            n_cols = -(-W // t)
            k = i * n_cols + j
            raw = zlib.decompress(self.blob[int(self.offsets[k]) : int(self.offsets[k + 1])])
            h, w = min(t, H - i * t), min(t, W - j * t)
            if self.unit_m is None:
                got = np.frombuffer(raw, dtype=np.dtype(self.dtype)).reshape(h, w)
            else:
                got = from_z16(_joined_counts(raw).reshape(h, w), self.unit_m)
            self._decoded[(i, j)] = got
        return got

    def _span(self, key, n: int) -> tuple[int, int] | int:
        if isinstance(key, slice):
            start, stop, step = key.indices(n)
            if step != 1:
                raise IndexError("TiledDepth: slices with a step are not supported")
            return start, max(stop, start)
        i = int(key)
        if i < -n or i >= n:
            raise IndexError(f"index {i} is out of bounds for axis with size {n}")
        return i + n if i < 0 else i

    def __getitem__(self, key):
        if not (isinstance(key, tuple) and len(key) == 2):
            raise IndexError("TiledDepth: index with [row, col] (integers or slices)")
        rows, cols = self._span(key[0], self.shape[0]), self._span(key[1], self.shape[1])
        t = self.tile
        if isinstance(rows, int) and isinstance(cols, int):
            return self._tile(rows // t, cols // t)[rows % t, cols % t]
        r0, r1 = (rows, rows + 1) if isinstance(rows, int) else rows
        c0, c1 = (cols, cols + 1) if isinstance(cols, int) else cols
        out = np.empty((r1 - r0, c1 - c0), dtype=np.dtype(self.dtype))
        for i in range(r0 // t, -(-r1 // t)):
            for j in range(c0 // t, -(-c1 // t)):
                a, b = max(r0, i * t), min(r1, (i + 1) * t)
                c, d = max(c0, j * t), min(c1, (j + 1) * t)
                tile = self._tile(i, j)
                out[a - r0 : b - r0, c - c0 : d - c0] = tile[a - i * t : b - i * t, c - j * t : d - j * t]
        if isinstance(rows, int):
            return out[0]
        if isinstance(cols, int):
            return out[:, 0]
        return out


def _split_bytes(counts: np.ndarray) -> bytes:
    """uint16 counts as their high bytes, then their low bytes."""
    b = counts.astype("<u2", copy=False).view(np.uint8).reshape(-1, 2)  # (n, 2): low, high
    return b[:, 1].tobytes() + b[:, 0].tobytes()


def _joined_counts(raw: bytes) -> np.ndarray:
    """The uint16 counts :func:`_split_bytes` wrote."""
    b = np.frombuffer(raw, np.uint8)
    n = b.size // 2
    out = np.empty((n, 2), np.uint8)
    out[:, 0], out[:, 1] = b[n:], b[:n]
    return out.view("<u2").ravel()


# ---------------------------------------------------------------------------- records


@dataclass(kw_only=True)
class FrameRecord:
    """What the pipeline after detection reads of one frame."""

    index: int
    timestamp_s: float
    pose: np.ndarray | None
    pose_confidence: str
    pose_relocalised: bool
    depth: TiledDepth | None
    detections: list[Detection]  # every detector's, in order; the ONNX detector's down to the floor
    qr_texts: dict[tuple[float, float, float, float], str]  # box -> text read, for QR boxes without text
    T_map_tracker_true: np.ndarray
    views: list[ObjectView] = field(default_factory=list)  # the objects the frame shows (ground truth)
    blur_px: float = 0.0  # the colour camera's motion blur


@dataclass(kw_only=True)
class PerceptionRecord:
    """A scenario's perception for one detector, and what a trial needs of its simulation."""

    key: str
    intrinsics: Intrinsics
    T_tracker_optical_nominal: np.ndarray
    drift_multiplier: float  # the arena's mean T265 drift multiplier (eval.trial.sensor_settings)
    truth_rows: list  # eval.scoring.truth rows (PoiRow)
    walls_map: list
    robot_path_map: np.ndarray
    times_s: np.ndarray
    n_frames: int
    notes: list[str]  # what choosing the detectors said (make_detectors)
    uses_oracle: bool
    labelled: bool  # the ONNX detector had a label classifier (its second conf test)
    qr_read: bool  # the QR reader could be imported, and read every QR box without text
    floor: float
    frames: list[FrameRecord]

    def replay_frames(self) -> Iterator[tuple[Frame, np.ndarray]]:
        """(frame as the pipeline sees it, true tracker pose) per recorded frame."""
        for f in self.frames:
            frame = Frame(
                index=f.index,
                timestamp_s=f.timestamp_s,
                rgb=EMPTY_RGB,
                intrinsics=self.intrinsics,
                depth_m=f.depth,
                pose=None if f.pose is None else f.pose.copy(),
                pose_confidence=f.pose_confidence,
                pose_relocalised=f.pose_relocalised,
            )
            yield frame, f.T_map_tracker_true


class ReplayDetector:
    """The recorded detections of each frame, the ONNX detector's filtered by ``conf`` (or
    ``type_conf`` of the detection's type) as it filters them itself: its float32 score test
    (``top_score >= conf``), and with a label classifier the float64 test of the named score
    (poi.detectors.onnx_yolo ``_postprocess``). Greedy NMS keeps a box whatever the lower-scored
    boxes are, so the boxes at or above their threshold among those kept at the floor are those
    a run at those thresholds keeps."""

    name = "replay"

    def __init__(self, record: PerceptionRecord, conf: float, type_conf: dict[str, float] | None = None) -> None:
        thresholds = {None: float(conf), **{t: float(c) for t, c in (type_conf or {}).items()}}
        for t, c in thresholds.items():
            if c < record.floor:
                key = "detector.conf" if t is None else f"detector.type_conf.{t}"
                raise ValueError(f"{key} {c} is below the recorded floor {record.floor}")
        self._by_index = {f.index: f for f in record.frames}
        self._thresholds = thresholds
        self._thresholds32 = {t: np.float32(c) for t, c in thresholds.items()}
        self._labelled = record.labelled
        self.current: FrameRecord | None = None
        self.highest_score = 0.0  # the best ONNX score recorded in the frames replayed (at or above the floor)

    def _keeps(self, d: Detection) -> bool:
        if d.source != ONNX_SOURCE:
            return True
        t = d.type if d.type in self._thresholds else None
        if not np.float32(d.confidence) >= self._thresholds32[t]:
            return False
        return not self._labelled or d.confidence >= self._thresholds[t]

    def detect(self, frame: Frame) -> list[Detection]:
        self.current = self._by_index[frame.index]
        scores = [d.confidence for d in self.current.detections if d.source == ONNX_SOURCE]
        self.highest_score = max([self.highest_score, *scores])
        # copies: the pipeline writes track ids into the detections it is given
        return [dataclasses.replace(d) for d in self.current.detections if self._keeps(d)]

    def read_qr(self, rgb: np.ndarray, detections: list[Detection], motion=None) -> list[Detection]:
        """``attach_qr_text`` for the current frame, from the texts recorded (read with the
        frame's motion then)."""
        texts = self.current.qr_texts if self.current is not None else {}
        return [dataclasses.replace(d, text=texts[tuple(d.box_xyxy)]) if d.type == "qr" else d for d in detections]


# -------------------------------------------------------------------------------- key


@functools.lru_cache(maxsize=1)
def code_fingerprint() -> str:
    """SHA-256 over the source (and data) that simulates and detects."""
    h = hashlib.sha256()
    paths = [ROOT / p for p in FINGERPRINT_FILES]
    for d in FINGERPRINT_DIRS:
        paths += [p for p in (ROOT / d).rglob("*") if p.is_file() and "__pycache__" not in p.parts]
    for p in sorted(paths):
        h.update(str(p.relative_to(ROOT)).encode())
        h.update(p.read_bytes())
    return h.hexdigest()


@functools.lru_cache(maxsize=16)
def _file_sha256(path: str, mtime_ns: int, size: int) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def file_sha256(path: str | Path) -> str | None:
    """SHA-256 of a file (remembered by path, mtime and size), None when there is none."""
    p = Path(path)
    if not p.is_file():
        return None
    st = p.stat()
    return _file_sha256(str(p.resolve()), st.st_mtime_ns, st.st_size)


def _library_versions() -> dict[str, str]:
    import cv2
    import mujoco
    import onnxruntime

    from sim.gl import renderer_identity

    return {
        "numpy": np.__version__,
        "mujoco": mujoco.__version__,
        "onnxruntime": onnxruntime.__version__,
        "cv2": cv2.__version__,
        "renderer": renderer_identity(),
    }


def perception_key(sc, detector: str, cfg, max_frames: int | None, model: Path | None) -> str | None:
    """The cache key of a trial's perception, or None when it cannot be replayed (a team's
    Python detector, whose code the key cannot cover, or ``detector.conf`` or a
    ``detector.type_conf`` below the floor).

    ``cfg`` is the pipeline config with the trial's settings; ``model`` the ONNX file the
    detector choice names (None for the oracle). Model files count by their SHA-256, so the same
    files at other paths (another checkout) give the same key."""
    from poi.config import config_to_dict

    if detector not in ("default", "oracle") and not detector.endswith(".onnx"):
        return None
    if min([cfg.detector.conf, *cfg.detector.type_conf.values()]) < CONF_FLOOR:
        return None
    # the thresholds act on the record; the label model counts by its bytes, not where it lies
    # (two checkouts of one repository share records)
    det = {
        k: v for k, v in config_to_dict(cfg)["detector"].items() if k not in ("conf", "type_conf", "label_model")
    }
    label = cfg.detector.label_model
    doc = {
        "format": CACHE_FORMAT,
        "code": code_fingerprint(),
        "libraries": _library_versions(),
        "scenario": sc.to_yaml(),
        "detector": detector,
        "model": None if model is None else file_sha256(model),
        "label_model": None if label is None else file_sha256(label),
        "detector_settings": det,
        # what the thermal detector does (confirm_colour_boxes acts after detection, on the record)
        "thermal": {k: v for k, v in config_to_dict(cfg)["thermal"].items() if k != "confirm_colour_boxes"},
        "max_frames": max_frames,
        "floor": CONF_FLOOR,
        "tile": TILE_PX,
    }
    return hashlib.sha256(json.dumps(doc, sort_keys=True, default=str).encode()).hexdigest()[:40]


# ------------------------------------------------------------------------------ store


def max_cache_bytes() -> int:
    """The cache's size limit: ``$POIBENCH_CACHE_MAX_GB`` gigabytes (10^9 bytes), default
    :data:`DEFAULT_MAX_GB`; a value that is not a number > 0 is a one-line error."""
    raw = os.environ.get(MAX_GB_ENV, "").strip()
    if not raw:
        return int(DEFAULT_MAX_GB * 1e9)
    try:
        gb = float(raw)
    except ValueError:
        gb = float("nan")
    if not (math.isfinite(gb) and gb > 0.0):
        raise PerceptionCacheError(f"{MAX_GB_ENV}={raw!r}: expected a number of gigabytes > 0")
    return int(gb * 1e9)


class PerceptionCache:
    """A folder of records, one file per key (see the module docstring), kept under ``max_bytes``
    (default :func:`max_cache_bytes`): after each store the least recently used records (a load
    marks a record used) are deleted until the folder fits, never the one just stored. Every
    change to the simulating or detecting source makes all older records unreadable, so
    without a limit the folder only grows (one day of development here: 77 GB)."""

    def __init__(self, folder: str | Path, max_bytes: int | None = None) -> None:
        self.folder = Path(folder)
        self.max_bytes = max_cache_bytes() if max_bytes is None else int(max_bytes)

    def path(self, key: str) -> Path:
        return self.folder / f"{key}{SUFFIX}"

    def load(self, key: str) -> PerceptionRecord | None:
        """The record of ``key``, or None when there is none or it is torn, corrupt or stale."""
        try:
            data = self.path(key).read_bytes()
        except OSError:
            return None
        if len(data) < HEADER.size:
            return None
        magic, fmt, length, crc = HEADER.unpack_from(data)
        payload = memoryview(data)[HEADER.size :]
        if magic != MAGIC or fmt != CACHE_FORMAT or length != len(payload) or zlib.crc32(payload) != crc:
            return None
        try:
            rec = pickle.loads(payload)
        except Exception:  # a record from another version of the classes: recompute it
            return None
        if not isinstance(rec, PerceptionRecord) or rec.key != key:
            return None
        with _suppress_os():
            os.utime(self.path(key))  # used now: the last the size limit evicts
        return rec

    def store(self, key: str, record: PerceptionRecord) -> None:
        """Write the record atomically (:func:`poi.core.atomic_file.atomic_path`)."""
        try:
            self.folder.mkdir(parents=True, exist_ok=True)
        except OSError as e:
            raise PerceptionCacheError(f"--cache {self.folder}: cannot create the folder ({e.strerror})") from None
        payload = pickle.dumps(record, protocol=pickle.HIGHEST_PROTOCOL)
        header = HEADER.pack(MAGIC, CACHE_FORMAT, len(payload), zlib.crc32(payload))
        # its temporary file, .NAME.RANDOM.tmp, is what _drop_stale_temps removes after a killed writer
        with atomic_path(self.path(key)) as tmp, open(tmp, "xb") as f:
            f.write(header)
            f.write(payload)
        self._drop_stale_temps()
        self._evict(keep=self.path(key))

    def _evict(self, keep: Path) -> None:
        """Delete the least recently used records until the folder's records fit ``max_bytes``
        (``keep``, the record just stored, stays whatever its size). Another worker may delete
        the same file first: that is no error."""
        records = []
        for p in self.folder.glob(f"*{SUFFIX}"):
            with _suppress_os():
                st = p.stat()
                records.append((st.st_mtime, p.name, st.st_size, p))
        total = sum(r[2] for r in records)
        for _, _, size, p in sorted(records):
            if total <= self.max_bytes:
                break
            if p == keep:
                continue
            with _suppress_os():
                p.unlink()
            total -= size

    def _drop_stale_temps(self) -> None:
        now = time.time()
        for p in self.folder.glob(".*.tmp"):
            with _suppress_os():
                if now - p.stat().st_mtime > STALE_TEMP_S:
                    p.unlink()


def _suppress_os():
    return contextlib.suppress(OSError)


def load_or_record(
    cache: PerceptionCache, key: str, record: Callable[[str], PerceptionRecord]
) -> PerceptionRecord:
    """The record of ``key`` from ``cache``; when missing, torn, corrupt or stale, ``record(key)``
    makes it and it is stored (eval.trial.sources.cached_perception). A cache that cannot be
    written (a full disk, a Ray node without the folder) costs the next trial its record,
    never this trial its result."""
    rec = cache.load(key)
    if rec is None:
        rec = record(key)
        with contextlib.suppress(OSError, PerceptionCacheError):
            cache.store(key, rec)
    return rec
