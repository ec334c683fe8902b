"""Reads a ROS log its writer never closed: a run stopped by SIGKILL, a crash or a power cut
leaves a log without the index its readers need.

* rosbag2 MCAP: the folder has no ``metadata.yaml`` and the file no summary or footer ([MCAP]:
  those are written when the file is closed; the data section before them is whole records, one
  after another, then the record being written when the writer stopped). Read as a stream of
  records with Foxglove's ``mcap`` reader.
* ROS 1 bag: the bag header's ``index_pos`` is still 0 (or points past the end of a cut file),
  and the connection and chunk-info records that follow the index are missing ([ROSBag]: a bag
  is a sequence of records, each a header of ``name=value`` fields with its ``op`` and a data
  part, both prefixed by their 4-byte little-endian length; chunk records hold the
  connection and message-data records, compressed as their header says). Read record by
  record here: the format is that small, and no maintained library reads a bag without its
  index.

Both are read up to the record cut short or the end of the file. The messages stamped with the
last log time read are left out: a trial writes a frame's messages at one stamp, so the frame
that was being written may be incomplete. What is handed on has the interface
:func:`eval.ros.reader.open_recording` reads through (``connections``, ``messages``,
``deserialize``), so a stopped run replays as a closed one does, up to where it stopped.

References
----------
Full entries in docs/SOURCES.md.

.. [MCAP] Foxglove, "MCAP file format specification".
.. [ROSBag] Open Robotics, "ROS Bag Format 2.0", ROS wiki.
"""

from __future__ import annotations

import bz2
import io
import struct
from abc import ABC, abstractmethod
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.msg import normalize_msgtype

ROS1_MAGIC = b"#ROSBAG V2.0"  # the first bytes of a ROS 1 bag, then a newline
ROS1_MAGIC_LINE = ROS1_MAGIC + b"\n"
OP_MESSAGE, OP_BAG_HEADER, OP_CHUNK, OP_CONNECTION = 0x02, 0x03, 0x05, 0x07


@dataclass(frozen=True)
class Connection:
    """A channel of the file: its topic and the ROS type of its messages."""

    id: int
    topic: str
    msgtype: str


class _Unclosed(ABC):
    """What both formats share: the connections and types found, the messages read again per
    ``messages`` without those of the last stamp, and the note. A format gives ``_scan``: every
    (kind, ...) item of the file in order, ``("connection", id, topic, type, definition)`` and
    ``("message", connection id, time ns, data)``, setting ``cut_short`` when a record is."""

    is2 = True

    def __init__(self, path: Path) -> None:
        self.path = path
        self.connections: list[Connection] = []
        self.n_messages = 0
        self.n_left_out = 0  # the messages of the last log time
        self.cut_short = False
        self._last_ns = -1
        types: dict = {}
        for item in self._scan():
            if item[0] == "connection":
                _, cid, topic, msgtype, definition = item
                if any(c.id == cid for c in self.connections):
                    continue  # a bag repeats a connection in each chunk that uses it
                types.update(get_types_from_msg(definition, msgtype))
                self.connections.append(Connection(cid, topic, msgtype))
            else:
                self.n_messages += 1
                if item[2] > self._last_ns:
                    self._last_ns, self.n_left_out = item[2], 0
                self.n_left_out += item[2] == self._last_ns
        self._typestore = get_typestore(Stores.EMPTY)
        self._typestore.register(types)

    @abstractmethod
    def _scan(self) -> Iterator[tuple]:
        """The file's items in order (class note)."""

    def messages(self, connections: list[Connection]) -> Iterator[tuple[Connection, int, bytes]]:
        """(connection, log time, serialised message) of ``connections``, in file order, without the
        messages of the last log time (see the module's note)."""
        wanted = {c.id: c for c in connections}
        for item in self._scan():
            if item[0] == "message" and item[1] in wanted and item[2] < self._last_ns:
                yield wanted[item[1]], item[2], item[3]

    def deserialize(self, raw: bytes, msgtype: str):
        if self.is2:
            return self._typestore.deserialize_cdr(raw, msgtype)
        return self._typestore.deserialize_ros1(raw, msgtype)

    def close(self) -> None:
        """Nothing is held open between reads (each opens and closes the file)."""
        return None

    def note(self) -> str:
        """One line for the replay's notes: what was read and what was left out."""
        end = "a record cut short" if self.cut_short else "the end of the file"
        where = self.path.parent if self.is2 else self.path
        why = "no metadata.yaml" if self.is2 else "no index"
        return (
            f"{where}: a recording never closed ({why}: the run stopped before its end?); read "
            f"{self.path.name} up to {end}: {self.n_messages - self.n_left_out} messages, leaving out the "
            f"{self.n_left_out} of the last stamp (the frame being written when it stopped)"
        )


class UnclosedMcap(_Unclosed):
    """A rosbag2 MCAP file without its summary, read with ``mcap``'s stream reader."""

    def _scan(self) -> Iterator[tuple]:
        from mcap.exceptions import McapError
        from mcap.records import Channel, Message, Schema
        from mcap.stream_reader import StreamReader

        schemas: dict[int, Schema] = {}
        with open(self.path, "rb") as f:
            try:
                for record in StreamReader(f).records:
                    if isinstance(record, Schema):
                        schemas[record.id] = record
                    elif isinstance(record, Channel):
                        schema = schemas.get(record.schema_id)
                        if schema is not None and schema.encoding == "ros2msg":  # what rosbag2 writes
                            yield "connection", record.id, record.topic, schema.name, schema.data.decode()
                    elif isinstance(record, Message):
                        yield "message", record.channel_id, record.log_time, record.data
            except (McapError, struct.error, EOFError):
                self.cut_short = True


def _fields(raw: bytes) -> dict[str, bytes]:
    """The ``name=value`` fields of a bag record header, each prefixed by its uint32 length."""
    out, at = {}, 0
    while at + 4 <= len(raw):
        (n,) = struct.unpack_from("<I", raw, at)
        name, _, value = raw[at + 4 : at + 4 + n].partition(b"=")
        out[name.decode()] = value
        at += 4 + n
    return out


def _records(f: io.BufferedIOBase | io.BytesIO) -> Iterator[tuple[dict[str, bytes], bytes]]:
    """(header fields, data) of each record from the current position; EOFError when one is cut short."""
    while True:
        head = f.read(4)
        if not head:
            return
        parts = []
        for length in (head, None):
            if length is None:
                length = f.read(4)
            if len(length) < 4:
                raise EOFError
            (n,) = struct.unpack("<I", length)
            body = f.read(n)
            if len(body) < n:
                raise EOFError
            parts.append(body)
        yield _fields(parts[0]), parts[1]


def bag_is_unclosed(path: Path) -> bool:
    """A ROS 1 bag whose header's ``index_pos`` is 0 (its writer never wrote the index) or points
    past the end of the file (cut)."""
    with open(path, "rb") as f:
        if f.read(len(ROS1_MAGIC_LINE)) != ROS1_MAGIC_LINE:
            return False
        try:
            fields, _ = next(_records(f))
        except (EOFError, StopIteration, struct.error):
            return True
    index_pos = struct.unpack("<Q", fields.get("index_pos", b"\0" * 8))[0]
    return index_pos == 0 or index_pos >= path.stat().st_size


_DECOMPRESS = {"none": lambda b: b, "bz2": bz2.decompress}


class UnclosedBag(_Unclosed):
    """A ROS 1 bag without its index, read record by record (module note)."""

    is2 = False

    def _scan(self) -> Iterator[tuple]:
        with open(self.path, "rb") as f:
            f.read(len(ROS1_MAGIC_LINE))
            try:
                yield from self._items(_records(f))
            except (EOFError, struct.error, OSError, ValueError):
                self.cut_short = True

    def _items(self, records: Iterator[tuple[dict[str, bytes], bytes]]) -> Iterator[tuple]:
        """The connections and messages of ``records``, those inside a chunk record included."""
        for fields, data in records:
            op = fields.get("op", b"\0")[0]
            if op == OP_CHUNK:
                yield from self._items(_records(io.BytesIO(self._unpacked(fields, data))))
            elif op == OP_CONNECTION:
                yield self._connection(fields, data)
            elif op == OP_MESSAGE:
                yield self._message(fields, data)

    @staticmethod
    def _unpacked(fields: dict[str, bytes], data: bytes) -> bytes:
        """A chunk record's data, decompressed as its header says."""
        compression = fields.get("compression", b"none").decode()
        if compression == "lz4":
            import lz4.frame  # rosbags' own dependency

            return lz4.frame.decompress(data)
        if compression in _DECOMPRESS:
            return _DECOMPRESS[compression](data)
        raise ValueError(f"chunk compression {compression!r}")

    @staticmethod
    def _connection(fields: dict[str, bytes], data: bytes) -> tuple:
        info = _fields(data)
        (cid,) = struct.unpack("<I", fields["conn"])
        msgtype = normalize_msgtype(info["type"].decode())
        return "connection", cid, fields["topic"].decode(), msgtype, info["message_definition"].decode()

    @staticmethod
    def _message(fields: dict[str, bytes], data: bytes) -> tuple:
        (cid,) = struct.unpack("<I", fields["conn"])
        sec, nsec = struct.unpack("<II", fields["time"])
        return "message", cid, sec * 1_000_000_000 + nsec, data
