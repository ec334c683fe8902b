"""``poibench run --help`` states what ``--log`` costs on disk, and the figure is the images'.

Measured: 40 frames of the default trial, 64.8 MB as MCAP and 64.8 MB as a ROS 1 bag, 1.62 MB
a frame; the colour, depth and thermal images (uncompressed) are 1.61 MB of it (99.6%).
"""

import re

import pytest

from eval.cli.main import build_parser
from eval.trial.scenarios import resolve_scenario


def _run_help(option: str) -> str:
    sub = next(a for a in build_parser()._actions if a.dest == "command")
    return next(a.help for a in sub.choices["run"]._actions if option in a.option_strings)


def test_the_log_help_gives_the_size_a_frame_of_the_default_trials_images():
    text = _run_help("--log")
    m = re.search(r"about ([\d.]+) MB a frame", text)
    assert m, text
    s = resolve_scenario(None, None, [], None).sensors
    rgb8, z16, float32 = 3, 2, 4  # bytes a pixel: colour rgb8, depth 16UC1, thermal 32FC1
    image_bytes = s.d435.width * s.d435.height * (rgb8 + z16) + s.thermal.width * s.thermal.height * float32
    # 5%: the help rounds to 0.1 MB; the messages' headers, poses and markers add 0.4%
    assert float(m[1]) * 1e6 == pytest.approx(image_bytes, rel=0.05)
