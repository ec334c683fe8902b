"""H.264 MP4 files through the ffmpeg binary that imageio-ffmpeg ships (no system ffmpeg)."""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np


class H264Writer:
    """Frames (RGB uint8) in, an H.264 MP4 out.

    x264 ``ultrafast`` at CRF 25 by default: on default-trial frames (640x480,
    sensor noise included) it took 3.1 ms of CPU per frame against 9.2 for
    ``veryfast`` and about 15 for the default preset, for a file of about 6 KB
    per frame; the cores are left to the simulator and the pipeline. One encoder
    thread (``-threads 1``): x264's own threads (frame threads and a lookahead
    thread, about 1.5 a core) cost 18% more CPU (3.2 against 2.65 ms a frame on
    trial frames; the same bytes' PSNR, 36.1 dB) and the trial keeps both cores
    busy anyway (issue 62).
    """

    def __init__(self, path: Path, width: int, height: int, fps: float, crf: int = 25) -> None:
        import imageio_ffmpeg

        self._gen = imageio_ffmpeg.write_frames(
            str(path),
            (width, height),
            fps=fps,
            codec="libx264",
            quality=None,
            macro_block_size=1,
            output_params=["-pix_fmt", "yuv420p", "-preset", "ultrafast", "-crf", str(crf), "-threads", "1"],
            ffmpeg_log_level="error",
        )
        self._gen.send(None)
        self.path = Path(path)
        self.frames = 0

    def write(self, rgb: np.ndarray) -> None:
        self._gen.send(np.ascontiguousarray(rgb))
        self.frames += 1

    def close(self) -> None:
        """Finish the file; one with no frame (a run that stopped before its first) is no video:
        it is removed, without imageio-ffmpeg's warning about it."""
        if self.frames:
            self._gen.close()
            return
        quiet = logging.getLogger("imageio_ffmpeg")
        level = quiet.level
        quiet.setLevel(logging.ERROR)
        try:
            self._gen.close()
        finally:
            quiet.setLevel(level)
        self.path.unlink(missing_ok=True)
