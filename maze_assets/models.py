"""MuJoCo geometry of every POI type, as MJCF ``<body>`` elements (rendering only).

``build_object`` returns ``<body name="poi_{id}_{type}" pos="x y z" euler="0 0 yaw">``
whose geoms are named ``poi_{id}_{type}_{part}`` (sim/objects.py). The euler angle
is in radians: the scene must declare ``<compiler angle="radian"/>`` (sim/world/world.py
does). Children use ``quat`` and ``fromto`` only, so they do not depend on it.

Local frame (sim/objects.py): origin at the object's reference point, +x the way
the object faces (out of the wall), z up. Every geom has ``contype="0"
conaffinity="0" group="0"``: nothing collides, everything renders.

Reference points and extents, for a characteristic size ``s = obj.size_m``:

- hazmat, qr, fire-extinguisher-sign: an ``s`` x ``s`` image; exit-sign: ``s`` wide
  and ``s/2`` high. The origin is on the wall face, the image is a textured quad at
  x = +3 mm (``QUAD_OFFSET_M``) over a thin backing; seen from +x it reads the
  right way round (the texture's top row at +z, its left column at -y).
- fire-extinguisher: ``s`` tall (0.5 m at RRL scale), radius 0.14 s, the origin at
  half height (floor at z = -s/2).
- valve: a hand wheel of diameter ``s`` centred on the origin, its axis along x, on a
  pipe from the wall at x = -0.48 s (``VALVE_STANDOFF``, sim/world/placement.py uses
  0.12 m for a 0.25 m wheel).
- door: a leaf ``s`` wide and :func:`door_height_m` high centred on the origin on the
  wall's centre line, in a frame ``DOOR_FRAME_M`` wide (:func:`door_frame_extent_m`).
- baby-doll: ``s`` long from feet to head along y, lying on its back, the origin at
  the torso centre, 0.06 s / 0.35 above the floor.
- heat-source: an oil-radiator-like heater ``s`` tall, ``s`` wide, 0.4 s deep, with a
  glowing orange-red grille on its +x face; the origin at its centroid.
- pillar-blue, pillar-red, pillar-green (the TurtleBot goal arena, [Bouda2025]_ section 1): a
  vertical cylinder ``s`` tall (``PILLAR_HEIGHT_M`` by default) and ``PILLAR_DIAMETER_M``
  across, standing on the floor, in a matte paint; the origin on its axis at half height
  (floor at z = -s/2).
- ball: a yellow sphere of diameter ``s`` (``BALL_DIAMETER_M``, a small football) resting
  on the floor; the origin at its centre.
- fiducial (the RMRC labyrinth's mapping fiducial, [RMRC2025]_ "Mapping"): half of a PVC
  pipe of diameter ``s`` (250-350 mm), ``FIDUCIAL_LENGTH_M`` (500 mm) long, standing on
  the floor with its axis vertical and its cut face against the wall: from above, half a
  circle. The origin is on the axis (on the wall face) at half its length (floor at
  z = -0.25 m); one exact mesh (:func:`half_cylinder_mesh`), matte grey PVC.
- landolt-c (the concentric Landolt-C target of the RMRC Sensor Cabinet and Linear Rail
  Inspect tests, [RMRC2025]_; poi/core/landolt.py): a matte white card ``s`` square (the
  rings' card, 64 mm for the default rings) printed with its rings (maze_assets.landolt,
  ``LANDOLT_TEXTURE_PX``), drawn as a flat item.
- holders (``PlacedObject.holder``): a flat item's board, cabinet, crate or ramp is a body of
  its own (:func:`build_holder`, named ``holder_{holder}_{id}``, so only the item's pixels belong
  to the object): a plywood board ``BOARD_THICKNESS_M`` thick on the wall, the item on its
  face (a Landolt-C card's ``LANDOLT_BOARD_M``, or one board for a placard, a QR code and a
  card, drawn by the placard); a grey box open to the front, ``LANDOLT_CABINET_M``, hung on
  the wall, a Landolt-C card on the inside of its back panel; or a pine crate open to the
  front, standing on the floor, a placard on the inside of its back panel
  (:func:`crate_inner_m`); or a solid wooden wedge against the wall, a placard lying on its
  slope (:func:`ramp_wedge`).

>>> from maze_assets.mjcf import SceneAssets
>>> from maze_assets.objects import PlacedObject
>>> body = build_object(PlacedObject(id=3, type="qr", text="Chart M"), SceneAssets())
>>> body.get("name"), [g.get("name") for g in body.iter("geom")]
('poi_3_qr', ['poi_3_qr_backing', 'poi_3_qr_face'])

References
----------
Full entries in docs/SOURCES.md.

.. [Bouda2025] M. Bouda, E. Doležal, O. Váňa, "Řešení úkolu pro TurtleBot s detekcí objektů
   a SLAM" ("A solution of the TurtleBot task with object detection and SLAM"), 2025.
.. [RMRC2025] RoboCup Rescue Rapidly Manufactured Robot Challenge rulebook, 2025.
"""

from __future__ import annotations

import hashlib
import xml.etree.ElementTree as ET

import numpy as np
from scipy.spatial.transform import Rotation

from maze_assets.hazmat import draw_hazmat, placard_style
from maze_assets.landolt import draw_landolt
from maze_assets.mjcf import SceneAssets, fmt
from maze_assets.objects import PlacedObject
from maze_assets.qr import QUIET_MODULES, draw_qr, qr_modules
from maze_assets.signs import draw_exit_sign, draw_fire_extinguisher_sign
from poi.core.landolt import LandoltSpec, parse_orientation_text

FLAT_TYPES = ("hazmat", "qr", "exit-sign", "fire-extinguisher-sign", "landolt-c")
CARD_RGBA = (0.95, 0.95, 0.94, 1.0)  # the white card behind a flat item, and a QR page
TEXTURE_PX = 256
QUAD_OFFSET_M = 0.003  # the image floats this far in front of the wall face
BACKING_M = 0.002  # thickness of the card / plate behind the image
# The part name of a flat item's backing (:func:`_flat`): see :func:`frames_item`.
BACKING_PART = "backing"
VALVE_STANDOFF = 0.48  # wall face to wheel centre, in wheel diameters
DOOR_FRAME_M = 0.05  # width of the jambs and the lintel
DOOR_MAX_HEIGHT_M = 2.0
DOLL_RRL_LENGTH_M = 0.35
FIRE_EXTINGUISHER_RADIUS = 0.14  # body radius per unit height (0.07 m at 0.5 m)
# The pillars of the [Bouda2025] arena are tubes about 5 cm across and 30-50 cm tall; its ball a small
# football (a size 4 ball is about 21 cm across): 0.40 m pillars and a 0.21 m ball.
PILLAR_DIAMETER_M = 0.05
PILLAR_HEIGHT_M = 0.40
BALL_DIAMETER_M = 0.21
# Matte paints (linear RGB) told apart under every lighting preset: the hues sit far apart
# (blue 225 deg, red 5 deg, green 135 deg) at similar brightness; specular kept low.
PILLAR_RGBA: dict[str, tuple[float, float, float, float]] = {
    "pillar-blue": (0.08, 0.22, 0.85, 1.0),
    "pillar-red": (0.85, 0.10, 0.07, 1.0),
    "pillar-green": (0.10, 0.62, 0.18, 1.0),
}
BALL_RGBA = (0.98, 0.85, 0.05, 1.0)
# The mapping fiducial ([RMRC2025] "Mapping", as issue 22 quotes it): "a 250-350 mm diameter PVC
# pipe cut in half, 500 mm long"; grey PVC, matte; the arc drawn with FIDUCIAL_SEGMENTS facets.
FIDUCIAL_DIAMETER_M = (0.25, 0.35)
FIDUCIAL_LENGTH_M = 0.50
FIDUCIAL_RGBA = (0.62, 0.64, 0.66, 1.0)
FIDUCIAL_SEGMENTS = 32
# Landolt-C holders: a plywood board (width, height, thickness) on the wall; a sensor cabinet
# (width, height, depth, wall thickness), a box open to the front hung on the wall.
LANDOLT_TEXTURE_PX = 512  # ring 5's 0.33 mm gap is 2.6 texels of the 64 mm card
LANDOLT_BOARD_M = (0.40, 0.30, 0.018)
LANDOLT_BOARD_RGBA = (0.76, 0.62, 0.42, 1.0)  # light plywood
LANDOLT_CABINET_M = (0.30, 0.30, 0.25, 0.012)
LANDOLT_CABINET_RGBA = (0.35, 0.37, 0.40, 1.0)  # grey-painted sheet metal
BOARD_THICKNESS_M = LANDOLT_BOARD_M[2]  # every board: 18 mm plywood
# A crate holding a placard (sim/world/placement.py put_placards_in_crates): open to the front, standing
# on the floor against a wall, the placard on the inside of its back panel. Inside it is
# CRATE_INNER_SIDES placard sides wide and high (a square sheet at 45 degrees, sqrt(2) sides across,
# fits) and CRATE_DEPTH_SIDES deep, with CRATE_WALL_M boards; rough pine, slats darker.
CRATE_INNER_SIDES = 1.5
CRATE_DEPTH_SIDES = 1.0
CRATE_WALL_M = 0.012
# A ramp holding a placard (sim/world/placement.py lay_placards_on_ramps): a solid wooden wedge against a
# wall, rising RAMP_SLOPE_DEG towards it (poibench's choice, a typical arena ramp's slope),
# RAMP_RUN_SIDES placard sides out from the wall and RAMP_WIDTH_SIDES wide, the placard lying
# in the middle of its slope.
RAMP_SLOPE_DEG = 15.0
RAMP_RUN_SIDES = 2.0
RAMP_WIDTH_SIDES = 2.4
RAMP_RGBA = (0.70, 0.58, 0.40, 1.0)
CRATE_RGBA = (0.62, 0.48, 0.30, 1.0)
CRATE_SLAT_RGBA = (0.45, 0.33, 0.20, 1.0)
ARENA_SIZE_M: dict[str, float] = {
    "pillar-blue": PILLAR_HEIGHT_M,
    "pillar-red": PILLAR_HEIGHT_M,
    "pillar-green": PILLAR_HEIGHT_M,
    "ball": BALL_DIAMETER_M,
}


class ModelError(ValueError):
    """An object that cannot be built (bad size or unknown type)."""


def door_height_m(wall_height_m: float) -> float:
    """Height of a door leaf in a wall of the given height: min(2.0, 0.9 * wall height).

    >>> door_height_m(1.2), door_height_m(3.0)
    (1.08, 2.0)
    """
    return min(DOOR_MAX_HEIGHT_M, 0.9 * wall_height_m)


def door_frame_extent_m(size_m: float, wall_height_m: float) -> tuple[float, float]:
    """(width, height above the floor) of a door's frame: the wall opening it fills.

    >>> door_frame_extent_m(0.8, 1.2)
    (0.9, 1.13)
    """
    return (size_m + 2 * DOOR_FRAME_M, round(door_height_m(wall_height_m) + DOOR_FRAME_M, 9))


DOOR_PANELS = ((0.10, 0.45), (0.55, 0.92))  # raised panels, as fractions of the leaf height
DOOR_PANEL_PROUD_M = 0.006  # a panel stands this far out of the leaf


def door_leaf_half_thickness_m(wall_thickness_m: float) -> float:
    """Half the thickness of a door leaf: 40 mm thick, or 0.8 of a thinner wall.

    >>> door_leaf_half_thickness_m(0.1), door_leaf_half_thickness_m(0.02)
    (0.02, 0.008)
    """
    return min(0.04, 0.8 * wall_thickness_m) / 2


def door_panel_face_m(wall_thickness_m: float) -> float:
    """Distance from the wall line to the face of a door's raised panels (where a sign sticks)."""
    return door_leaf_half_thickness_m(wall_thickness_m) + DOOR_PANEL_PROUD_M


def flat_extent_m(type_: str, size_m: float) -> tuple[float, float]:
    """(width, height) of a flat item's image, metres.

    >>> flat_extent_m("exit-sign", 0.3)
    (0.3, 0.15)
    """
    if type_ not in FLAT_TYPES:
        raise ModelError(f"flat_extent_m: {type_!r} is not a flat type {FLAT_TYPES}")
    return (size_m, size_m / 2) if type_ == "exit-sign" else (size_m, size_m)


# --- small helpers ------------------------------------------------------------------------


def _set_asset_attr(assets: SceneAssets, tag: str, name: str, **attrs: str) -> None:
    """Set attributes SceneAssets has no argument for (mesh inertia, material emission)."""
    for el in assets.asset.iter(tag):
        if el.get("name") == name:
            for k, v in attrs.items():
                el.set(k, v)
            return
    raise KeyError(f"no <{tag} name={name!r}> in the scene assets")


def _material(assets: SceneAssets, name: str, rgba, *, emission: float = 0.0, **kw) -> str:
    """A shared material ``objmat_{name}`` (registered on first use)."""
    full = f"objmat_{name}"
    if not assets.has(full):
        assets.material(full, rgba=rgba, **kw)
        if emission:
            _set_asset_attr(assets, "material", full, emission=fmt(emission))
    return full


def body_rotation(obj: PlacedObject) -> Rotation:
    """An object body's orientation in the world: its yaw about z, the tilt lifting its face
    normal (+x) up, the roll about that normal."""
    return Rotation.from_euler("ZYX", [obj.yaw, -obj.tilt, obj.roll])


def frames_item(geom_name: str) -> bool:
    """Whether a box around the item framed this geom of an object's body: every geom but a
    flat item's backing. The backing fills the 3 mm between the wall and the image floating in
    front of it (``QUAD_OFFSET_M``, which keeps the two from fighting in the depth buffer); a
    real placard is paper on the wall. Seen at an angle, the backing's edge at the wall lies
    up to 3 mm sin(angle) beside the image's: 2 px at 0.7 m and 60 degrees, as much as the
    box centre's whole error there. A detector's label frames the printed sign, and so do the
    simulator's truth boxes (docs/CONSISTENCY.md "A sign's box frames its image, not its
    backing").

    >>> frames_item("poi_3_qr_face"), frames_item("poi_3_qr_backing")
    (True, False)
    """
    return not geom_name.endswith("_" + BACKING_PART)


def reference_point(obj: PlacedObject) -> np.ndarray:
    """Where the object is, as a report should name it (:class:`PlacedObject`'s ``position``
    says which point): its body origin, except a flat item's, whose origin is on the face it
    hangs on while its image floats ``QUAD_OFFSET_M`` in front (:func:`_quad_mesh`): the centre
    of that image. The 3 mm matter to a covariance check, not to a score: a sign's depth is its
    image's, and at 0.6 m the D435's noise is 1.3 mm.

    >>> reference_point(PlacedObject(id=0, type="qr", yaw=np.pi / 2)).round(6).tolist()
    [0.0, 0.003, 0.0]
    >>> reference_point(PlacedObject(id=0, type="door")).tolist()
    [0.0, 0.0, 0.0]
    """
    p = np.asarray(obj.position, dtype=float)
    if obj.type not in FLAT_TYPES:
        return p.copy()
    return p + QUAD_OFFSET_M * body_rotation(obj).apply([1.0, 0.0, 0.0])


class _Body:
    """Adds named, non-colliding geoms to one object body."""

    def __init__(self, obj: PlacedObject, assets: SceneAssets) -> None:
        self.obj, self.assets = obj, assets
        if obj.roll == 0.0 and obj.tilt == 0.0:
            turn = {"euler": fmt([0.0, 0.0, obj.yaw])}
        else:  # yaw about world z, the tilt lifting the face normal (+x) up, the roll about it
            x, y, z, w = body_rotation(obj).as_quat()
            turn = {"quat": fmt([w, x, y, z])}
        self.el = ET.Element("body", name=obj.body_name, pos=fmt(obj.position), **turn)
        self._parts: set[str] = set()

    def geom(self, part: str, material: str, **attrs) -> ET.Element:
        if part in self._parts:
            raise ModelError(f"{self.obj.body_name}: part {part!r} used twice")
        self._parts.add(part)
        a = {k: (v if isinstance(v, str) else fmt(v)) for k, v in attrs.items()}
        return ET.SubElement(
            self.el,
            "geom",
            name=f"{self.obj.body_name}_{part}",
            material=material,
            contype="0",
            conaffinity="0",
            group="0",
            **a,
        )

    def box(self, part: str, material: str, lo, hi, quat=None) -> ET.Element:
        """Axis-aligned box between corners lo and hi (local frame), optionally rotated."""
        lo, hi = np.asarray(lo, float), np.asarray(hi, float)
        extra = {} if quat is None else {"quat": quat}
        return self.geom(part, material, type="box", pos=(lo + hi) / 2, size=np.abs(hi - lo) / 2, **extra)

    def capsule(self, part: str, material: str, p0, p1, r: float) -> ET.Element:
        return self.geom(part, material, type="capsule", fromto=[*p0, *p1], size=r)

    def cylinder(self, part: str, material: str, p0, p1, r: float) -> ET.Element:
        return self.geom(part, material, type="cylinder", fromto=[*p0, *p1], size=r)

    def sphere(self, part: str, material: str, p, r: float) -> ET.Element:
        return self.geom(part, material, type="sphere", pos=p, size=r)

    def ellipsoid(self, part: str, material: str, p, radii) -> ET.Element:
        return self.geom(part, material, type="ellipsoid", pos=p, size=radii)


# --- flat items ---------------------------------------------------------------------------


def placard_key(obj: PlacedObject) -> str:
    """The asset key of a placard with its own print (``objtex_{key}``, ``objmat_{key}``)."""
    return f"hazmat_{obj.text}_{obj.look_seed}"


def _flat_texture(obj: PlacedObject, assets: SceneAssets) -> tuple[str, float]:
    """Register (once) the texture and material for a flat item; (material, emission)."""
    glossy = False
    if obj.type == "hazmat" and obj.look_seed is not None:
        style = placard_style(obj.text, obj.look_seed)
        key, glossy = placard_key(obj), style.look.laminated
        draw = lambda: draw_hazmat(obj.text, TEXTURE_PX, style)  # noqa: E731
    elif obj.type == "hazmat":
        key, draw = f"hazmat_{obj.text}", lambda: draw_hazmat(obj.text, TEXTURE_PX)
    elif obj.type == "qr":
        digest = hashlib.sha1(obj.text.encode("utf-8")).hexdigest()[:12]
        key, draw = f"qr_{digest}", lambda: draw_qr(obj.text, TEXTURE_PX)
    elif obj.type == "landolt-c":
        try:
            rings = parse_orientation_text(obj.text)
        except ValueError as e:
            raise ModelError(f"object {obj.id} (landolt-c): {e}") from None
        spec = LandoltSpec()
        if sorted(rings) != list(range(1, spec.n_rings + 1)):
            raise ModelError(
                f"object {obj.id} (landolt-c): its text {obj.text!r} must give rings 1 to {spec.n_rings} once each"
            )
        orient = [rings[k] for k in sorted(rings)]
        key = "landolt_" + "_".join(str(o) for o in orient)
        draw = lambda: draw_landolt(LandoltSpec(), orient, LANDOLT_TEXTURE_PX)  # noqa: E731
    elif obj.type == "exit-sign":
        key, draw = "exit_sign", lambda: draw_exit_sign(TEXTURE_PX)
    else:
        key, draw = "fire_extinguisher_sign", lambda: draw_fire_extinguisher_sign(TEXTURE_PX)
    tex, mat = f"objtex_{key}", f"objmat_{key}"
    if not assets.has(tex):
        assets.texture(tex, draw())
    if not assets.has(mat):
        # an exit sign is a lit box: it glows a little
        # a laminated placard's film gives a highlight where a lamp mirrors in it
        spec, shine = (0.6, 0.8) if glossy else (0.05, 0.05)
        assets.material(mat, texture=tex, specular=spec, shininess=shine)
        if obj.type == "exit-sign":
            _set_asset_attr(assets, "material", mat, emission="0.4")
    return mat, 0.0


def _quad_mesh(assets: SceneAssets, w: float, h: float) -> str:
    """A w x h quad in the y-z plane at x = QUAD_OFFSET_M, facing +x, image upright.

    Vertices 0..3 are top-left, top-right, bottom-right, bottom-left as seen from +x
    (the viewer's right is +y); texcoord (0, 0) is the image's top-left pixel (checked
    by rendering in tests/maze_assets/test_models.py).
    """
    name = f"objmesh_quad_{round(w * 1e4)}x{round(h * 1e4)}"
    if assets.has(name):
        return name
    x = QUAD_OFFSET_M
    V = [(x, -w / 2, h / 2), (x, w / 2, h / 2), (x, w / 2, -h / 2), (x, -w / 2, -h / 2)]
    F = [(0, 3, 2), (0, 2, 1)]  # counter-clockwise seen from +x: the normal is +x
    UV = [(0, 0), (1, 0), (1, 1), (0, 1)]
    assets.mesh(name, V, F, UV)
    _set_asset_attr(assets, "mesh", name, inertia="shell")  # a flat mesh has no volume
    return name


def _diamond_mesh(assets: SceneAssets, w: float) -> str:
    """The diamond inscribed in a w x w quad (as :func:`_quad_mesh`): a placard cut out.

    Vertices top, right, bottom, left as seen from +x; their texcoords are the midpoints
    of the texture's edges, where the printed diamond's corners are.
    """
    name = f"objmesh_diamond_{round(w * 1e4)}"
    if assets.has(name):
        return name
    x, r = QUAD_OFFSET_M, w / 2
    V = [(x, 0.0, r), (x, r, 0.0), (x, 0.0, -r), (x, -r, 0.0)]
    F = [(0, 3, 2), (0, 2, 1)]
    UV = [(0.5, 0.0), (1.0, 0.5), (0.5, 1.0), (0.0, 0.5)]
    assets.mesh(name, V, F, UV)
    _set_asset_attr(assets, "mesh", name, inertia="shell")
    return name


def _flat(b: _Body) -> None:
    obj = b.obj
    w, h = flat_extent_m(obj.type, obj.size_m)
    mat, _ = _flat_texture(obj, b.assets)
    backing = _material(b.assets, "card", CARD_RGBA)
    if obj.type == "hazmat" and obj.look_seed is not None and placard_style(obj.text, obj.look_seed).look.cut:
        # cut out along the diamond: a square plate turned 45 degrees about the normal
        side = w / np.sqrt(2.0)
        q45 = [np.cos(np.pi / 8), np.sin(np.pi / 8), 0.0, 0.0]
        b.box(BACKING_PART, backing, (0.0, -side / 2, -side / 2), (BACKING_M, side / 2, side / 2), quat=q45)
        b.geom("face", mat, type="mesh", mesh=_diamond_mesh(b.assets, w))
        return
    b.box(BACKING_PART, backing, (0.0, -w / 2, -h / 2), (BACKING_M, w / 2, h / 2))
    b.geom("face", mat, type="mesh", mesh=_quad_mesh(b.assets, w, h))


# --- free-standing and wall objects -------------------------------------------------------


def _fire_extinguisher(b: _Body) -> None:
    H = b.obj.size_m
    r = FIRE_EXTINGUISHER_RADIUS * H
    z0 = -H / 2  # floor
    a = b.assets
    red = _material(a, "extinguisher_red", (0.78, 0.05, 0.04, 1.0), specular=0.5, shininess=0.6)
    black = _material(a, "rubber_black", (0.05, 0.05, 0.05, 1.0), specular=0.2)
    steel = _material(a, "steel", (0.72, 0.72, 0.74, 1.0), specular=0.8, shininess=0.8)
    white = _material(a, "label_white", (0.95, 0.95, 0.93, 1.0))
    top = z0 + 0.72 * H
    b.cylinder("base", black, (0, 0, z0), (0, 0, z0 + 0.03 * H), 1.02 * r)
    b.cylinder("body", red, (0, 0, z0 + 0.02 * H), (0, 0, top), r)
    b.ellipsoid("shoulder", red, (0, 0, top), (r, r, 0.45 * r))
    b.cylinder("label", white, (0, 0, z0 + 0.30 * H), (0, 0, z0 + 0.56 * H), 1.01 * r)
    b.box(
        "label_text",
        black,
        (1.0 * r, -0.35 * r, z0 + 0.44 * H),
        (1.02 * r, 0.35 * r, z0 + 0.47 * H),
    )
    b.cylinder("neck", steel, (0, 0, top + 0.4 * r), (0, 0, z0 + 0.84 * H), 0.28 * r)
    b.box("valve", steel, (-0.35 * r, -0.3 * r, z0 + 0.83 * H), (0.45 * r, 0.3 * r, z0 + 0.90 * H))
    b.cylinder("gauge", white, (0.45 * r, 0, z0 + 0.865 * H), (0.52 * r, 0, z0 + 0.865 * H), 0.2 * r)
    b.capsule("lever", black, (-0.2 * r, 0, z0 + 0.92 * H), (1.1 * r, 0, z0 + 0.975 * H), 0.07 * r)
    b.capsule("handle", black, (-0.2 * r, 0, z0 + 0.89 * H), (1.1 * r, 0, z0 + 0.87 * H), 0.07 * r)
    hose = [
        (0.0, 0.3 * r, z0 + 0.86 * H),
        (0.0, 1.25 * r, z0 + 0.80 * H),
        (0.0, 1.30 * r, z0 + 0.62 * H),
        (0.0, 1.18 * r, z0 + 0.42 * H),
    ]
    for k, (p, q) in enumerate(zip(hose[:-1], hose[1:], strict=False)):
        b.capsule(f"hose_{k}", black, p, q, 0.09 * r)
    b.cylinder("nozzle", black, hose[-1], (0.0, 1.12 * r, z0 + 0.28 * H), 0.16 * r)


def _valve(b: _Body) -> None:
    D = b.obj.size_m
    a = b.assets
    grey = _material(a, "pipe_grey", (0.55, 0.57, 0.58, 1.0), specular=0.5, shininess=0.5)
    iron = _material(a, "cast_iron", (0.22, 0.23, 0.24, 1.0), specular=0.3)
    steel = _material(a, "steel", (0.72, 0.72, 0.74, 1.0), specular=0.8, shininess=0.8)
    if b.obj.id % 2 == 0:
        wheel = _material(a, "wheel_red", (0.80, 0.08, 0.06, 1.0), specular=0.4, shininess=0.5)
    else:
        wheel = _material(a, "wheel_yellow", (0.95, 0.75, 0.05, 1.0), specular=0.4, shininess=0.5)
    xw = -VALVE_STANDOFF * D  # wall face
    b.cylinder("flange", grey, (xw, 0, 0), (xw + 0.025 * D, 0, 0), 0.18 * D)
    b.cylinder("pipe", grey, (xw, 0, 0), (-0.20 * D, 0, 0), 0.08 * D)
    b.ellipsoid("body", iron, (-0.15 * D, 0, 0), (0.09 * D, 0.14 * D, 0.14 * D))
    b.cylinder("bonnet", iron, (-0.10 * D, 0, 0), (-0.03 * D, 0, 0), 0.07 * D)
    b.cylinder("stem", steel, (-0.04 * D, 0, 0), (0.025 * D, 0, 0), 0.022 * D)
    b.cylinder("hub", wheel, (-0.02 * D, 0, 0), (0.02 * D, 0, 0), 0.07 * D)
    R, tube, n = 0.45 * D, 0.045 * D, 18
    ang = np.linspace(0.0, 2 * np.pi, n + 1)
    for k in range(n):
        p = (0.0, R * np.cos(ang[k]), R * np.sin(ang[k]))
        q = (0.0, R * np.cos(ang[k + 1]), R * np.sin(ang[k + 1]))
        b.capsule(f"rim_{k}", wheel, p, q, tube)
    for k in range(4):
        t = np.pi / 4 + k * np.pi / 2
        b.capsule(f"spoke_{k}", wheel, (0.0, 0.0, 0.0), (0.0, R * np.cos(t), R * np.sin(t)), 0.6 * tube)


def _door(b: _Body, wall_height_m: float, wall_thickness_m: float) -> None:
    W = b.obj.size_m
    H = door_height_m(wall_height_m)
    a = b.assets
    wood = _material(a, "door_leaf", (0.55, 0.32, 0.16, 1.0), specular=0.2, shininess=0.3)
    panel = _material(a, "door_panel", (0.47, 0.27, 0.13, 1.0), specular=0.2, shininess=0.3)
    frame = _material(a, "door_frame", (0.93, 0.92, 0.88, 1.0), specular=0.2)
    steel = _material(a, "steel", (0.72, 0.72, 0.74, 1.0), specular=0.8, shininess=0.8)
    fw = DOOR_FRAME_M
    fd = wall_thickness_m / 2 + 0.005  # frame half depth: 5 mm proud of each wall face
    t = door_leaf_half_thickness_m(wall_thickness_m)
    gap = 0.003
    z0 = -H / 2
    for side, s in (("left", 1), ("right", -1)):
        y_in = s * W / 2
        b.box(f"jamb_{side}", frame, (-fd, y_in, z0), (fd, y_in + s * fw, H / 2 + fw))
    b.box("lintel", frame, (-fd, -W / 2, H / 2), (fd, W / 2, H / 2 + fw))
    b.box("leaf", wood, (-t, -W / 2 + gap, z0 + gap), (t, W / 2 - gap, H / 2 - gap))
    # two raised panels on each face
    mw = 0.12 * W
    zs = [(z0 + a * H, z0 + b * H) for a, b in DOOR_PANELS]
    for face, sx in (("front", 1), ("back", -1)):
        for k, (za, zb) in enumerate(zs):
            x0, x1 = sorted((sx * (t - 0.002), sx * (t + DOOR_PANEL_PROUD_M)))  # embedded: no z-fighting
            b.box(f"panel_{face}_{k}", panel, (x0, -W / 2 + mw, za), (x1, W / 2 - mw, zb))
    # lever handles on both faces, on the side away from the hinges (+y jamb holds the hinges)
    zh = z0 + min(1.0, 0.5 * H)
    yh = -W / 2 + 0.07
    for face, sx in (("front", 1), ("back", -1)):
        b.cylinder(f"rose_{face}", steel, (sx * t, yh, zh), (sx * (t + 0.012), yh, zh), 0.025)
        b.capsule(f"neck_{face}", steel, (sx * t, yh, zh), (sx * (t + 0.05), yh, zh), 0.009)
        b.capsule(
            f"lever_{face}",
            steel,
            (sx * (t + 0.05), yh, zh),
            (sx * (t + 0.05), yh + 0.11, zh),
            0.011,
        )
    for k, zf in enumerate((0.15, 0.85)):
        zz = z0 + zf * H
        b.cylinder(f"hinge_{k}", steel, (0, W / 2 - 0.005, zz - 0.04), (0, W / 2 - 0.005, zz + 0.04), 0.008)


def _baby_doll(b: _Body) -> None:
    s = b.obj.size_m / DOLL_RRL_LENGTH_M  # metres below are at the RRL size (0.35 m long)
    a = b.assets
    skin = _material(a, "doll_skin", (0.96, 0.78, 0.66, 1.0), specular=0.2, shininess=0.3)
    hair = _material(a, "doll_hair", (0.55, 0.36, 0.18, 1.0), specular=0.1)
    dark = _material(a, "doll_eye", (0.08, 0.06, 0.06, 1.0))
    lips = _material(a, "doll_mouth", (0.80, 0.35, 0.38, 1.0))
    if b.obj.id % 2 == 0:
        cloth = _material(a, "onesie_pink", (0.97, 0.70, 0.80, 1.0), specular=0.05)
    else:
        cloth = _material(a, "onesie_blue", (0.62, 0.80, 0.96, 1.0), specular=0.05)

    def p(x, y, z):
        return (x * s, y * s, z * s)

    # lying on its back along y (head at +y), face up; torso centre at the origin, floor at -0.06
    b.capsule("torso", cloth, p(0, -0.02, 0), p(0, 0.04, 0), 0.055 * s)
    b.sphere("head", skin, p(0, 0.12, 0.0), 0.055 * s)
    b.ellipsoid("hair", hair, p(0, 0.135, -0.005), (0.056 * s, 0.05 * s, 0.052 * s))
    for side, sx in (("left", 1), ("right", -1)):
        b.sphere(f"eye_{side}", dark, p(0.02 * sx, 0.125, 0.051), 0.007 * s)
        b.capsule(
            f"arm_{side}",
            cloth,
            p(0.062 * sx, 0.055, -0.02),
            p(0.075 * sx, -0.02, -0.03),
            0.021 * s,
        )
        b.sphere(f"hand_{side}", skin, p(0.077 * sx, -0.038, -0.032), 0.019 * s)
        b.capsule(
            f"leg_{side}",
            cloth,
            p(0.03 * sx, -0.06, -0.028),
            p(0.035 * sx, -0.15, -0.032),
            0.027 * s,
        )
    b.ellipsoid("mouth", lips, p(0, 0.095, 0.047), (0.012 * s, 0.005 * s, 0.004 * s))


def _heat_source(b: _Body) -> None:
    H = b.obj.size_m
    a = b.assets
    body = _material(a, "heater_body", (0.88, 0.88, 0.86, 1.0), specular=0.4, shininess=0.4)
    fin = _material(a, "heater_fin", (0.80, 0.80, 0.78, 1.0), specular=0.4, shininess=0.4)
    glow = _material(a, "heater_glow", (1.0, 0.32, 0.06, 1.0), emission=0.9, specular=0.1)
    chrome = _material(a, "steel", (0.72, 0.72, 0.74, 1.0), specular=0.8, shininess=0.8)
    dark = _material(a, "rubber_black", (0.05, 0.05, 0.05, 1.0), specular=0.2)
    z0 = -H / 2
    xb, xf = -0.20 * H, 0.20 * H  # back and front faces
    nf = 7
    pitch = H / nf
    for k in range(nf):  # vertical fins behind the front panel
        yc = -H / 2 + pitch * (k + 0.5)
        b.box(f"fin_{k}", fin, (xb, yc - 0.35 * pitch, z0 + 0.10 * H), (0.0, yc + 0.35 * pitch, H / 2))
    b.box("panel", body, (0.0, -H / 2, z0 + 0.08 * H), (xf - 0.01 * H, H / 2, H / 2))
    b.box("grille", glow, (xf - 0.01 * H, -0.40 * H, z0 + 0.25 * H), (xf, 0.40 * H, z0 + 0.85 * H))
    for k in range(6):  # guard bars across the glowing grille
        zz = z0 + 0.25 * H + (k + 0.5) * 0.6 * H / 6
        b.capsule(
            f"bar_{k}",
            chrome,
            (xf + 0.01 * H, -0.40 * H, zz),
            (xf + 0.01 * H, 0.40 * H, zz),
            0.008 * H,
        )
    b.box("base", dark, (xb - 0.05 * H, -0.45 * H, z0), (xf + 0.05 * H, -0.35 * H, z0 + 0.08 * H))
    b.box("base_2", dark, (xb - 0.05 * H, 0.35 * H, z0), (xf + 0.05 * H, 0.45 * H, z0 + 0.08 * H))
    b.cylinder("knob", dark, (0.05 * H, 0.35 * H, H / 2), (0.05 * H, 0.35 * H, H / 2 + 0.04 * H), 0.04 * H)


def _pillar(b: _Body) -> None:
    H = b.obj.size_m
    paint = _material(
        b.assets, b.obj.type.replace("-", "_"), PILLAR_RGBA[b.obj.type], specular=0.05, shininess=0.05
    )
    b.cylinder("body", paint, (0, 0, -H / 2), (0, 0, H / 2), PILLAR_DIAMETER_M / 2)


def _ball(b: _Body) -> None:
    yellow = _material(b.assets, "ball_yellow", BALL_RGBA, specular=0.15, shininess=0.2)
    b.sphere("body", yellow, (0, 0, 0), b.obj.size_m / 2)


def half_cylinder_mesh(radius_m: float, length_m: float, segments: int = FIDUCIAL_SEGMENTS):
    """Vertices (N, 3) and outward-facing triangles (M, 3) of a closed half-cylinder.

    The axis is z (from -length/2 to +length/2), the curved side on x >= 0 (angles -90 to
    +90 degrees in ``segments`` facets), the flat cut face in the plane x = 0. The side,
    the two end caps and the flat face have their own vertices, so MuJoCo's vertex normals
    stay smooth round the side and sharp at the edges.

    >>> V, F = half_cylinder_mesh(0.15, 0.5, 4)
    >>> V.shape, F.shape, float(V[:, 0].max()), float(V[:, 1].min()), float(V[:, 2].max())
    ((24, 3), (16, 3), 0.15, -0.15, 0.25)
    """
    if not (radius_m > 0 and length_m > 0 and segments >= 2):
        raise ModelError(
            f"half_cylinder_mesh: radius and length must be > 0 and segments >= 2, got "
            f"{radius_m}, {length_m}, {segments}"
        )
    a = np.linspace(-np.pi / 2, np.pi / 2, segments + 1)  # (S+1,)
    ring = np.c_[radius_m * np.cos(a), radius_m * np.sin(a)]  # (S+1, 2)
    ring[[0, -1], 0] = 0.0  # the ends of the arc lie exactly on the cut face
    h = length_m / 2
    S = segments + 1
    side = np.r_[np.c_[ring, np.full(S, -h)], np.c_[ring, np.full(S, h)]]  # bottom ring, then top ring
    bottom = np.c_[ring, np.full(S, -h)]
    top = np.c_[ring, np.full(S, h)]
    flat = np.array([[0.0, -radius_m, -h], [0.0, radius_m, -h], [0.0, radius_m, h], [0.0, -radius_m, h]])
    V = np.r_[side, bottom, top, flat]
    F: list[tuple[int, int, int]] = []
    for k in range(segments):  # side: counter-clockwise seen from outside
        b0, b1, t0, t1 = k, k + 1, S + k, S + k + 1
        F += [(b0, b1, t1), (b0, t1, t0)]
    ob, ot = 2 * S, 3 * S
    for k in range(1, segments):  # caps: fans from the arc's first point (on the cut face)
        F.append((ob, ob + k + 1, ob + k))  # bottom faces -z
        F.append((ot, ot + k, ot + k + 1))  # top faces +z
    of = 4 * S
    F += [(of, of + 2, of + 1), (of, of + 3, of + 2)]  # the cut face faces -x
    return V, np.asarray(F, dtype=int)


def qr_side_m(text: str, module_m: float) -> float:
    """Side of a QR object's image (quiet zone included) whose modules are ``module_m`` wide.

    The texture is ``TEXTURE_PX`` pixels with an integer number of pixels per module
    (maze_assets.qr.draw_qr), so the side is TEXTURE_PX / (pixels per module) modules.

    >>> round(qr_side_m("Chart A 2mm", 0.002), 4)  # 21 modules + 8 quiet: 8 px a module, 32 modules
    0.064
    """
    m = qr_modules(text).shape[0] + 2 * QUIET_MODULES
    return TEXTURE_PX / (TEXTURE_PX // m) * module_m


def crate_inner_m(placard_side_m: float) -> tuple[float, float]:
    """(inner width = inner height, inner depth) of the crate that holds a placard of this side.

    >>> crate_inner_m(0.25)
    (0.375, 0.25)
    """
    return CRATE_INNER_SIDES * placard_side_m, CRATE_DEPTH_SIDES * placard_side_m


def holder_name(obj: PlacedObject) -> str:
    """The body name of an object's holder: ``holder_{kind}_{id}`` (no object owns its pixels)."""
    return f"holder_{obj.holder}_{obj.id}"


def build_holder(obj: PlacedObject, assets: SceneAssets) -> ET.Element | None:
    """A flat item's board, sensor cabinet, crate or ramp (``PlacedObject.holder``) as a ``<body>``
    of its own named by :func:`holder_name`, or None without a holder or where another item of a
    shared board draws it (``holder_m`` None).

    The body's origin is on the wall face behind the item (the item's reference point less its
    standoff, ``holder_standoff_m``), its +x out of the wall. A board is a plywood panel over
    ``holder_m``; a cabinet the grey box ``LANDOLT_CABINET_M`` open to the front; a crate a pine
    box over ``holder_m`` (its floor on the ground), ``crate_inner_m`` deep inside, open to the
    front, with two darker slats across each side; a ramp the wedge of :func:`_ramp`."""
    if obj.holder is None or (obj.holder != "cabinet" and obj.holder_m is None):
        return None
    yaw = obj.yaw
    n = np.array([np.cos(yaw), np.sin(yaw), 0.0])
    name = holder_name(obj)
    kw = {"contype": "0", "conaffinity": "0", "group": "0"}
    if obj.holder == "ramp":
        return _ramp(obj, assets, name, kw)
    origin = obj.position - n * holder_standoff_m(obj.holder)
    body = ET.Element("body", name=name, pos=fmt(origin), euler=fmt([0.0, 0.0, yaw]))

    def box(part: str, material: str, pos, size) -> None:
        ET.SubElement(
            body, "geom", name=f"{name}_{part}", type="box", material=material, pos=fmt(pos), size=fmt(size), **kw
        )

    if obj.holder == "board":
        t = BOARD_THICKNESS_M
        left, right, bottom, top = obj.holder_m
        wood = _material(assets, "plywood", LANDOLT_BOARD_RGBA, specular=0.05, shininess=0.05)
        box(
            "panel",
            wood,
            (t / 2, (left + right) / 2, (bottom + top) / 2),
            (t / 2, (right - left) / 2, (top - bottom) / 2),
        )
        return body
    if obj.holder == "cabinet":
        w, h, d, t = LANDOLT_CABINET_M
        y0, z0 = 0.0, 0.0
        panel = _material(assets, "cabinet_grey", LANDOLT_CABINET_RGBA, specular=0.2, shininess=0.2)
    else:  # crate
        t = CRATE_WALL_M
        left, right, bottom, top = obj.holder_m
        w, h = right - left, top - bottom
        d = crate_inner_m(obj.size_m)[1] + t
        y0, z0 = (left + right) / 2, (bottom + top) / 2
        panel = _material(assets, "crate_pine", CRATE_RGBA, specular=0.03, shininess=0.05)
        slat = _material(assets, "crate_slat", CRATE_SLAT_RGBA, specular=0.03, shininess=0.05)
        for side, y in (("left", y0 - w / 2 - 0.004), ("right", y0 + w / 2 + 0.004)):
            for j, z in enumerate((z0 - h / 4, z0 + h / 4)):
                box(f"slat_{side}_{j}", slat, (d / 2, y, z), (d / 2, 0.004, 0.02))
    panels = {  # (centre x, y, z), half sizes (x, y, z) in the body frame
        "back": ((t / 2, y0, z0), (t / 2, w / 2, h / 2)),
        "left": ((d / 2, y0 - w / 2 + t / 2, z0), (d / 2, t / 2, h / 2)),
        "right": ((d / 2, y0 + w / 2 - t / 2, z0), (d / 2, t / 2, h / 2)),
        "top": ((d / 2, y0, z0 + h / 2 - t / 2), (d / 2, w / 2, t / 2)),
        "bottom": ((d / 2, y0, z0 - h / 2 + t / 2), (d / 2, w / 2, t / 2)),
    }
    for part, (pos, size) in panels.items():
        box(part, panel, pos, size)
    return body


def ramp_wedge(run_m: float, width_y: tuple[float, float], slope_rad: float) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (6, 3) and outward triangles (8, 3) of a solid wedge: its back on the wall (x = 0)
    ``run_m tan(slope)`` high, its slope falling to the floor at x = ``run_m``, over y in
    ``width_y``.

    >>> V, F = ramp_wedge(0.5, (-0.3, 0.3), np.radians(15))
    >>> round(float(V[:, 2].max()), 4), V.shape, F.shape
    (0.134, (6, 3), (8, 3))
    """
    h = run_m * np.tan(slope_rad)
    y0, y1 = width_y
    V = np.array([[0, y0, 0], [run_m, y0, 0], [0, y0, h], [0, y1, 0], [run_m, y1, 0], [0, y1, h]], dtype=float)
    F = np.array(
        [
            (0, 1, 2),  # side at y0 (faces -y)
            (3, 5, 4),  # side at y1 (faces +y)
            (0, 4, 1),  # bottom (faces -z)
            (0, 3, 4),
            (0, 5, 3),  # back on the wall (faces -x)
            (0, 2, 5),
            (1, 5, 2),  # the slope (faces up and out)
            (1, 4, 5),
        ]
    )  # counter-clockwise seen from outside: each face's normal points away from the wedge
    return V, F


def _ramp(obj: PlacedObject, assets: SceneAssets, name: str, kw: dict) -> ET.Element:
    """A placard's ramp (``holder_m``: its slope's extent about the placard, before the roll):
    a wedge whose slope holds the placard, standing on the floor against the wall behind it."""
    slope = np.pi / 2 - obj.tilt
    n = np.array([np.cos(obj.yaw), np.sin(obj.yaw)])
    left, right, bottom, top = obj.holder_m  # bottom and top: down and up the slope
    normal = np.array([*(np.cos(obj.tilt) * n), np.sin(obj.tilt)])
    q = obj.position - normal * holder_standoff_m("ramp")  # on the slope, under the placard
    foot = q[:2] - n * top * np.cos(slope)  # the slope's top edge meets the wall there
    run = (top - bottom) * np.cos(slope)
    mesh = f"holdermesh_ramp_{obj.id}"
    assets.mesh(mesh, *ramp_wedge(float(run), (left, right), float(slope)))
    wood = _material(assets, "ramp_wood", RAMP_RGBA, specular=0.05, shininess=0.05)
    body = ET.Element("body", name=name, pos=fmt([foot[0], foot[1], 0.0]), euler=fmt([0.0, 0.0, obj.yaw]))
    ET.SubElement(body, "geom", name=f"{name}_wedge", type="mesh", mesh=mesh, material=wood, **kw)
    return body


def holder_standoff_m(holder: str | None) -> float:
    """How far a held item's face stands out from the surface behind it: the board's thickness,
    the cabinet's back panel or the crate's, a floor placard's lift off a ramp's slope; 0 on the
    wall itself."""
    return {
        None: 0.0,
        "board": BOARD_THICKNESS_M,
        "cabinet": LANDOLT_CABINET_M[3],
        "crate": CRATE_WALL_M,
        "ramp": BACKING_M + 0.001,  # lying on the slope, as a floor placard on the floor
    }[holder]


def build_page(obj: PlacedObject, assets: SceneAssets) -> ET.Element | None:
    """The white A4 page under a QR code that carries ``page_m``, as a ``<body>`` of its own
    (named ``qr_page_{id}``, not ``poi_...``: no object owns its pixels), or None."""
    if obj.page_m is None:
        return None
    left, right, bottom, top = obj.page_m
    paper = _material(assets, "card", CARD_RGBA)  # the same white as the codes' own backing
    body = ET.Element("body", name=f"qr_page_{obj.id}", pos=fmt(obj.position), euler=fmt([0.0, 0.0, obj.yaw]))
    ET.SubElement(
        body,
        "geom",
        name=f"qr_page_{obj.id}_sheet",
        type="box",
        material=paper,
        contype="0",
        conaffinity="0",
        group="0",
        pos=fmt([BACKING_M / 4, (left + right) / 2, (bottom + top) / 2]),
        size=fmt([BACKING_M / 4, (right - left) / 2, (top - bottom) / 2]),
    )
    return body


def _fiducial(b: _Body) -> None:
    r = b.obj.size_m / 2
    name = f"objmesh_fiducial_{round(b.obj.size_m * 1e4)}"
    if not b.assets.has(name):
        V, F = half_cylinder_mesh(r, FIDUCIAL_LENGTH_M)
        b.assets.mesh(name, V, F)
    pvc = _material(b.assets, "pvc_grey", FIDUCIAL_RGBA, specular=0.1, shininess=0.1)
    b.geom("body", pvc, type="mesh", mesh=name)


def build_object(
    obj: PlacedObject,
    assets: SceneAssets,
    *,
    wall_height_m: float = 1.2,
    wall_thickness_m: float = 0.05,
) -> ET.Element:
    """The ``<body>`` of ``obj`` (see the module docstring for each type's geometry).

    Textures and materials are registered in ``assets`` once and shared between
    objects of the same look (same hazmat label, same QR text).
    """
    if not obj.size_m > 0:
        raise ModelError(f"object {obj.id} ({obj.type}): size_m must be > 0, got {obj.size_m}")
    b = _Body(obj, assets)
    if obj.type in FLAT_TYPES:
        _flat(b)
    elif obj.type == "fire-extinguisher":
        _fire_extinguisher(b)
    elif obj.type == "valve":
        _valve(b)
    elif obj.type == "door":
        if not (wall_height_m > 0 and wall_thickness_m > 0):
            raise ModelError(
                f"object {obj.id} (door): wall_height_m and wall_thickness_m must be > 0, "
                f"got {wall_height_m}, {wall_thickness_m}"
            )
        _door(b, wall_height_m, wall_thickness_m)
    elif obj.type == "baby-doll":
        _baby_doll(b)
    elif obj.type == "heat-source":
        _heat_source(b)
    elif obj.type in PILLAR_RGBA:
        _pillar(b)
    elif obj.type == "ball":
        _ball(b)
    elif obj.type == "fiducial":
        _fiducial(b)
    else:  # PlacedObject already checks the type; this guards a new type without a model
        raise ModelError(f"object {obj.id}: no model for type {obj.type!r}")
    return b.el
