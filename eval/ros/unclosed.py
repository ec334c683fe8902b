"""Reads the MCAP file of a rosbag2 recording its writer never closed: a run stopped by SIGKILL,
a crash or a power cut leaves the folder without ``metadata.yaml`` and the file without its
summary and footer, which the rosbag2 readers need ([MCAP]: the summary section and footer are
written when the file is closed; the data section before them is complete records, one after
another).

The data section is read from the start as a stream, record by record, until the record that
was being written when the writer stopped (cut short) or the end of the file. The messages
stamped with the last log time read are left out: a trial writes a frame's messages at one
stamp, so the frame that was being written may be incomplete. What is handed on has the
interface :func:`eval.ros.reader.open_recording` reads through (``connections``,
``messages``, ``deserialize``), so a stopped run replays as a closed one does, up to where it
stopped.

References
----------
Full entries in docs/SOURCES.md.

.. [MCAP] Foxglove, "MCAP file format specification".
"""

from __future__ import annotations

import struct
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

from mcap.exceptions import McapError
from mcap.records import Channel, Message, Schema
from mcap.stream_reader import StreamReader
from rosbags.typesys import Stores, get_types_from_msg, get_typestore


@dataclass(frozen=True)
class Connection:
    """A channel of the file: its topic and the ROS type of its messages."""

    id: int
    topic: str
    msgtype: str


class UnclosedMcap:
    """The whole records of an unclosed MCAP file, read once at open and again per ``messages``."""

    is2 = True  # CDR, as rosbag2 writes it

    def __init__(self, path: Path) -> None:
        self.path = path
        self.connections: list[Connection] = []
        self.n_messages = 0
        self.n_left_out = 0  # the messages of the last log time
        self.cut_short = False
        self._last_ns = -1
        schemas: dict[int, Schema] = {}
        types: dict = {}
        for record in self._records():
            if isinstance(record, Schema):
                schemas[record.id] = record
            elif isinstance(record, Channel):
                schema = schemas.get(record.schema_id)
                if schema is None or schema.encoding != "ros2msg":
                    continue  # not a ROS 2 message channel: nothing here reads it
                types.update(get_types_from_msg(schema.data.decode(), schema.name))
                self.connections.append(Connection(record.id, record.topic, schema.name))
            elif isinstance(record, Message):
                self.n_messages += 1
                if record.log_time > self._last_ns:
                    self._last_ns, self.n_left_out = record.log_time, 0
                self.n_left_out += record.log_time == self._last_ns
        self._typestore = get_typestore(Stores.EMPTY)
        self._typestore.register(types)

    def _records(self) -> Iterator:
        """The file's records in order, up to the first that is cut short (``cut_short`` then True)."""
        with open(self.path, "rb") as f:
            try:
                yield from StreamReader(f).records
            except (McapError, struct.error, EOFError):
                self.cut_short = True

    def messages(self, connections: list[Connection]) -> Iterator[tuple[Connection, int, bytes]]:
        """(connection, log time, serialised message) of ``connections``, in file order, without the
        messages of the last log time (see the module's note)."""
        wanted = {c.id: c for c in connections}
        for record in self._records():
            if isinstance(record, Message) and record.channel_id in wanted and record.log_time < self._last_ns:
                yield wanted[record.channel_id], record.log_time, record.data

    def deserialize(self, raw: bytes, msgtype: str):
        return self._typestore.deserialize_cdr(raw, msgtype)

    def close(self) -> None:
        """Nothing is held open between reads."""

    def note(self) -> str:
        """One line for the replay's notes: what was read and what was left out."""
        end = "a record cut short" if self.cut_short else "the end of the file"
        return (
            f"{self.path.parent}: a recording never closed (no metadata.yaml: the run stopped before its end?); "
            f"read {self.path.name} up to {end}: {self.n_messages - self.n_left_out} messages, leaving out the "
            f"{self.n_left_out} of the last stamp (the frame being written when it stopped)"
        )
