"""The record of one point of interest placed in the world.

Every object is a MuJoCo body named ``poi_{id}_{type}`` whose geoms are named
``poi_{id}_{type}_{part}``, so segmentation ids map back to objects without
guessing (see :func:`object_id_from_geom_name`).

Local frame of an object body: origin at the object's reference point (the
point written to the ground truth), +x the direction the object faces (out of
the wall for wall-mounted objects), z up. ``yaw`` turns that frame about the
world z axis.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

import numpy as np

from poi.core.names import TYPES

MOUNTS = ("wall", "floor", "opening")
# What a flat item may be fixed to, and which types each holder takes (sim/world/placement.py,
# maze_assets.models.build_holder): a wooden board on the wall (a Landolt-C card alone, or a
# group of a placard, a QR code and a Landolt-C card), a sensor cabinet (Landolt-C), an open
# crate standing on the floor (a placard on the inside of its back panel) or a wooden ramp
# against a wall (a placard lying on its slope).
HOLDER_TYPES: dict[str, tuple[str, ...]] = {
    "board": ("hazmat", "qr", "landolt-c"),
    "cabinet": ("landolt-c",),
    "crate": ("hazmat",),
    "ramp": ("hazmat",),
}

_GEOM_RE = re.compile(r"^poi_(\d+)_([a-z\-]+)(?:_.*)?$")


@dataclass(kw_only=True)
class PlacedObject:
    """One POI in the world frame.

    ``position`` is the body's origin in world coordinates (metres) and, for all but the
    flat items, the reference point a report names: the centre of a door leaf, the centre
    of a valve's wheel, the centroid of a free-standing object (a pillar's: on its axis at
    half its height; the ball's: its centre). A flat item's origin is the centre of the
    face it hangs on, and its reference point the centre of its image, 3 mm in front
    (maze_assets.models.reference_point). ``size_m`` is the object's characteristic
    size (a placard's side, a door's width, a doll's length). ``temperature_c``
    is what the thermal camera sees on its surface (None: ambient). ``look_seed``
    picks a placard's printed variant (maze_assets.hazmat.placard_style; None: the
    canonical design). ``roll`` turns a flat item about its face normal (radians,
    counter-clockwise as a viewer facing it sees it). ``tilt`` lifts the face normal
    from horizontal towards +z (radians; pi/2: lying face up on the floor, its top edge
    towards ``yaw`` + pi).
    """

    id: int
    type: str
    text: str = ""
    position: np.ndarray = field(default_factory=lambda: np.zeros(3))
    yaw: float = 0.0
    mount: str = "wall"
    size_m: float = 0.2
    temperature_c: float | None = None
    wall: str | None = None  # name of the wall segment it hangs on or replaces
    look_seed: int | None = None
    roll: float = 0.0
    tilt: float = 0.0
    # The A4 page a QR code is printed on (the first code of a page carries it): (left, right,
    # bottom, top) of the page in the object's local (y, z), metres; drawn as a white sheet on the
    # wall, not part of the object (maze_assets.models.build_page).
    page_m: tuple[float, float, float, float] | None = None
    module_m: float | None = None  # a QR code's module side, metres (None: whatever its size gives)
    # What a flat item is fixed to (``HOLDER_TYPES``; sim/world/placement.py, maze_assets.models.
    # build_holder): None (the wall itself), "board" (a wooden board on the wall), "cabinet" (the
    # back of a sensor cabinet, a box open to the front hung on the wall), "crate" (the inside
    # of an open crate's back panel) or "ramp" (the slope of a ramp against a wall); drawn
    # apart from the object.
    holder: str | None = None
    # The board's or crate's front face, or the ramp's slope, (left, right, bottom, top) in the
    # object's local (y, z) before its roll, metres (a ramp's bottom and top: down and up the
    # slope), for the one object that draws it; None on the other items of a shared board (and
    # on a cabinet, whose size is fixed).
    holder_m: tuple[float, float, float, float] | None = None

    def __post_init__(self) -> None:
        if self.type not in TYPES:
            raise ValueError(f"object {self.id}: unknown type {self.type!r}; expected one of {TYPES}")
        if self.mount not in MOUNTS:
            raise ValueError(f"object {self.id}: mount must be one of {MOUNTS}, got {self.mount!r}")
        if self.holder is not None and self.type not in HOLDER_TYPES.get(self.holder, ()):
            takes = [h for h, types in HOLDER_TYPES.items() if self.type in types]
            raise ValueError(
                f"object {self.id} ({self.type}): holder {self.holder!r} is not for this type; "
                f"expected one of {takes or 'none'}"
            )
        if self.holder_m is not None:
            left, right, bottom, top = self.holder_m
            if self.holder not in ("board", "crate", "ramp") or not (left < 0 < right and bottom < 0 < top):
                raise ValueError(
                    f"object {self.id}: holder_m {self.holder_m} must be a board's, crate's or ramp's face "
                    "(left, right, bottom, top) around the object"
                )
        self.position = np.asarray(self.position, dtype=float).reshape(3)

    @property
    def body_name(self) -> str:
        return f"poi_{self.id}_{self.type}"


def object_id_from_geom_name(name: str | None) -> int | None:
    """Object id from a geom (or body) name following ``poi_{id}_{type}_{part}``.

    >>> object_id_from_geom_name("poi_12_fire-extinguisher_body")
    12
    >>> object_id_from_geom_name("wall_0_1_n") is None
    True
    """
    if not name:
        return None
    m = _GEOM_RE.match(name)
    return int(m.group(1)) if m else None


def fiducial_text(diameter_m: float) -> str:
    """A fiducial's ground-truth text: its pipe diameter, which the map draws it at.

    >>> fiducial_text(0.3), fiducial_diameter_m("300 mm"), fiducial_diameter_m("")
    ('300 mm', 0.3, None)
    """
    return f"{round(diameter_m * 1000):d} mm"


def fiducial_diameter_m(text: str) -> float | None:
    """The diameter a fiducial's text gives (:func:`fiducial_text`), or None."""
    parts = text.split()
    if len(parts) == 2 and parts[1] == "mm":
        try:
            return float(parts[0]) / 1000
        except ValueError:
            return None
    return None
