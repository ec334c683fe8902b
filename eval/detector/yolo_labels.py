"""YOLO label files: one line a box, ``class cx cy w h``, the class an index of
:data:`poi.core.names.RESCUE_CLASSES` and the box's centre and size normalised to the image
(Ultralytics' detection format). Every command that reads labels (``evaluate-detector``,
``evaluate-photos``, ``sim2real``, ``calibrate``, ``train``) reads them here, so a bad line is
refused the same way everywhere: one line naming the file and line number.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from poi.core.names import RESCUE_CLASSES


@dataclass(frozen=True)
class YoloBox:
    """One label line: the class index and the normalised centre and size."""

    cls: int
    cx: float
    cy: float
    w: float
    h: float

    @property
    def xyxy(self) -> tuple[float, float, float, float]:
        """Corners (x1, y1, x2, y2), normalised."""
        return (self.cx - self.w / 2, self.cy - self.h / 2, self.cx + self.w / 2, self.cy + self.h / 2)

    def line(self, cls: int | None = None) -> str:
        """The label line (class ``cls`` in place of its own when given); the numbers as Python
        writes floats, which read back to the same values."""
        return f"{self.cls if cls is None else cls} {self.cx} {self.cy} {self.w} {self.h}"


def yolo_box_problem(cx: float, cy: float, w: float, h: float) -> str | None:
    """What is wrong with a YOLO box's normalised centre and size (each a number in [0, 1], the
    size above 0), or None: a NaN or out-of-range box would count as a placard no detector
    can find.

    >>> yolo_box_problem(0.5, 0.5, 0.1, 0.1) is None, yolo_box_problem(float("nan"), 0.5, 0.1, 0.1)
    (True, 'cx nan: expected a number in [0, 1]')
    """
    for name, v in (("cx", cx), ("cy", cy), ("w", w), ("h", h)):
        if not 0.0 <= v <= 1.0:
            return f"{name} {v:g}: expected a number in [0, 1]"
    return None if w > 0 and h > 0 else f"w {w:g}, h {h:g}: expected a box larger than 0"


def read_yolo_labels(path: Path, error: type[ValueError] = ValueError) -> list[YoloBox]:
    """The boxes of label file ``path`` (blank lines skipped); ``error`` with ``FILE:LINE`` and
    what was expected for a line that is not five fields, a class outside RESCUE_CLASSES, or a
    box :func:`yolo_box_problem` refuses.

    >>> import tempfile
    >>> f = Path(tempfile.mkdtemp()) / "a.txt"
    >>> _ = f.write_text("3 0.5 0.5 0.2 0.1\\n")
    >>> read_yolo_labels(f)[0].xyxy
    (0.4, 0.45, 0.6, 0.55)
    """
    boxes = []
    for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
        parts = line.split()
        if not parts:
            continue
        if len(parts) != 5:
            raise error(f"{path}:{n}: expected 'class cx cy w h', got {len(parts)} fields")
        try:
            cls = int(parts[0])
        except ValueError:
            raise error(f"{path}:{n}: class index {parts[0]!r} is not an integer") from None
        if not 0 <= cls < len(RESCUE_CLASSES):
            raise error(f"{path}:{n}: class index {cls} is not in 0..{len(RESCUE_CLASSES) - 1}")
        try:
            cx, cy, w, h = map(float, parts[1:])
        except ValueError:
            raise error(f"{path}:{n}: expected 'class cx cy w h' with numbers, got {line.strip()!r}") from None
        problem = yolo_box_problem(cx, cy, w, h)
        if problem:
            raise error(f"{path}:{n}: {problem}")
        boxes.append(YoloBox(cls, cx, cy, w, h))
    return boxes
