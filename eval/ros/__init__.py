"""ROS logs in and out: a trial written as a rosbag2 (MCAP) or ROS 1 bag, and a robot's recording
replayed through the pipeline.

One module a job: :mod:`eval.ros.topics` (topic and frame names, the realsense-ros defaults and
the RealSense Viewer's layout), :mod:`eval.ros.messages` (messages to and from arrays),
:mod:`eval.ros.align` (depth aligned to colour), :mod:`eval.ros.reader` (a recording as frames),
:mod:`eval.ros.writer` (a trial as a log, on a thread of its own), :mod:`eval.ros.unclosed` (the
MCAP file of a log its run never closed) and :mod:`eval.ros.replay` (the pipeline over a
recording, with a trial's outputs). The library under all of them is ``rosbags`` [rosbags]_ (pure
Python; reads and writes ROS 1 bags and rosbag2 in sqlite3 or MCAP storage without ROS
installed), with Foxglove's ``mcap`` reader for the unclosed files; both are the ``ros`` extra.

References
----------
Full entries in docs/SOURCES.md.

.. [rosbags] Ternaris, "rosbags: pure Python library to read, modify, convert and write rosbag
   files", Apache-2.0.
"""

from __future__ import annotations


class RosExtraError(RuntimeError):
    """The ``ros`` extra (rosbags) is not installed; one line saying how to install it."""


def require_rosbags(command: str) -> None:
    """Refuse ``command`` with one line when ``rosbags`` cannot be imported."""
    try:
        import rosbags  # noqa: F401
    except ImportError:
        raise RosExtraError(
            f"{command} needs the rosbags library: pip install 'poibench[ros]' (or pip install rosbags)"
        ) from None
