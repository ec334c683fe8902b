"""Canonical object types, hazmat labels and the aliases real teams write.

Implements the "Type names" and "Hazmat labels" sections of docs/RULES.md: matching is
case-insensitive and treats spaces, ``_`` and ``-`` alike.

The detector's class space (``CLASSES``) is the 16 hazmat labels followed by the
eight other rescue types (``RESCUE_CLASSES``, the 24 classes of the rescue
detector's datasets and models), then the four types of the TurtleBot goal arena
(``ARENA_TYPES``: [Bouda2025]_ section 1, the blue goal pillars, the other pillars and
the ball), then the Landolt-C target (``TARGET_TYPES``), so one class name says both the
type and, for hazmats, the label.
Rescue types and classes keep their order and indices; the arena's are appended.

>>> canonical_type("QR Code")
'qr'
>>> canonical_type("fire extinguisher")
'fire-extinguisher'
>>> canonical_label("Toxic")
'inhalation-hazard'
>>> class_to_identity("oxidizer")
('hazmat', 'oxidizer')
>>> class_to_identity("baby_doll")
('baby-doll', '')
>>> display_name("hazmat", "oxidizer")
'Oxidizer'
>>> canonical_type("Blue pillar"), class_to_identity("ball"), display_name("pillar-blue")
('pillar-blue', ('ball', ''), 'Blue pillar')
>>> len(RESCUE_CLASSES), len(CLASSES), CLASSES[len(RESCUE_CLASSES):] == ARENA_TYPES + TARGET_TYPES
(24, 29, True)

References
----------
Full entries in docs/SOURCES.md.

.. [Avevor2022] E. Avevor, "Proposed solution to RoboCupRescue EX3", University of Cambridge,
   2022.
.. [Bouda2025] M. Bouda, E. Doležal, O. Váňa, "Řešení úkolu pro TurtleBot s detekcí objektů
   a SLAM" ("A solution of the TurtleBot task with object detection and SLAM"), 2025.
.. [RMRC2025] RoboCup Rescue Rapidly Manufactured Robot Challenge rulebook, 2025.
"""

from __future__ import annotations

# The RoboCupRescue "recognize objects" types (docs/RULES.md "Type names").
RESCUE_TYPES: tuple[str, ...] = (
    "hazmat",
    "qr",
    "door",
    "valve",
    "baby-doll",
    "fire-extinguisher",
    "exit-sign",
    "fire-extinguisher-sign",
    "heat-source",
)

# The TurtleBot goal arena ([Bouda2025] section 1, tasks 2 and 3): two blue pillars mark the
# goal, pillars of other colours stand behind it, and a yellow ball lies before it.
ARENA_TYPES: tuple[str, ...] = (
    "pillar-blue",
    "pillar-red",
    "pillar-green",
    "ball",
)

# Map landmarks of the RMRC labyrinth ([RMRC2025]_, "Mapping"): the fiducials, half-cylinders of
# PVC pipe mounted in pairs facing each other on walls. Not points of interest: no preset scores
# them, but the QR mapping bonus is judged by the distances to them (eval/scoring/scorer.py).
MAPPING_TYPES: tuple[str, ...] = ("fiducial",)

# Visual-acuity targets of the RMRC Sensor Cabinet and Linear Rail Inspect tests ([RMRC2025]_): the
# concentric Landolt-C (poi/core/landolt.py). Their text is the rings' gap directions
# (docs/RULES.md "Landolt-C"); a detector class of its own domain (no model confuses it).
TARGET_TYPES: tuple[str, ...] = ("landolt-c",)

# Every canonical type: the rescue types first (their order is part of the file formats
# and the class indices), then the arena's, then the map landmarks, then the targets.
TYPES: tuple[str, ...] = RESCUE_TYPES + ARENA_TYPES + MAPPING_TYPES + TARGET_TYPES
# types whose identity includes what is read off their face, a placard's label, a code's text, a
# target's gaps, as the shipped rules score them (docs/RULES.md rule 1): the in-view test needs
# their face (poi.core.in_view); the funnel's read stage takes identity from the trial's rules
TEXT_IDENTITY_TYPES: tuple[str, ...] = ("hazmat", "qr", "landolt-c")

HAZMAT_LABELS: tuple[str, ...] = (
    "explosive",
    "blasting-agent",
    "flammable-gas",
    "non-flammable-gas",
    "oxygen",
    "fuel-oil",
    "dangerous-when-wet",
    "flammable-solid",
    "spontaneously-combustible",
    "oxidizer",
    "organic-peroxide",
    "inhalation-hazard",
    "poison",
    "radioactive",
    "corrosive",
    "infectious-substance",
)

TYPE_ALIASES: dict[str, str] = {
    "placard": "hazmat",
    "hazmat-placard": "hazmat",
    "hazmat-sign": "hazmat",
    "qrcode": "qr",
    "qr-code": "qr",
    "doll": "baby-doll",
    "victim": "baby-doll",
    "baby": "baby-doll",
    "extinguisher": "fire-extinguisher",
    "exit": "exit-sign",
    "heat": "heat-source",
    "hotspot": "heat-source",
    "thermal": "heat-source",
    "blue-pillar": "pillar-blue",
    "red-pillar": "pillar-red",
    "green-pillar": "pillar-green",
    "yellow-ball": "ball",
    "football": "ball",
    "fiducials": "fiducial",
    "mapping-fiducial": "fiducial",
    "landolt": "landolt-c",
    "landoltc": "landolt-c",
    "landolt-ring": "landolt-c",
}

LABEL_ALIASES: dict[str, str] = {
    "explosives": "explosive",
    "blasting-agents": "blasting-agent",
    "flammable": "flammable-gas",
    "flammable-liquid": "flammable-gas",
    "dangerous": "dangerous-when-wet",
    "poison-gas": "inhalation-hazard",
    "toxic": "inhalation-hazard",
    "infectious": "infectious-substance",
    "organic-peroxides": "organic-peroxide",
}

# Detector class space: hazmat labels first, then every other rescue type, then the
# arena types (class = type). Text-bearing types other than hazmat (qr) get their text
# from a decoder, not the class. The rescue detector's datasets and models have exactly
# RESCUE_CLASSES, a prefix of CLASSES, so their class indices are the same in both.
RESCUE_CLASSES: tuple[str, ...] = HAZMAT_LABELS + tuple(t for t in RESCUE_TYPES if t != "hazmat")
CLASSES: tuple[str, ...] = RESCUE_CLASSES + ARENA_TYPES + TARGET_TYPES
CLASS_INDEX: dict[str, int] = {name: i for i, name in enumerate(CLASSES)}
# The object type each class names, index for index with CLASSES (and RESCUE_CLASSES, its
# prefix): 'hazmat' for every placard label, the class itself for every other type.
CLASS_TYPES: tuple[str, ...] = tuple("hazmat" if c in HAZMAT_LABELS else c for c in CLASSES)

# What an operator reads where the type name written as a sentence would read badly.
DISPLAY_NAMES: dict[str, str] = {
    "pillar-blue": "Blue pillar",
    "pillar-red": "Red pillar",
    "pillar-green": "Green pillar",
}


def class_domain(class_name: str) -> tuple[str, ...]:
    """The class space a class of CLASSES belongs to: ARENA_TYPES, TARGET_TYPES or
    RESCUE_CLASSES. A detector of one domain never reports the other's classes, so it spreads a
    detection's 1 - p over its own domain ([Avevor2022]_ section 2.1.5).

    >>> len(class_domain("door")), class_domain("ball") == ARENA_TYPES, class_domain("landolt-c")
    (24, True, ('landolt-c',))
    """
    if class_name in ARENA_TYPES:
        return ARENA_TYPES
    if class_name in TARGET_TYPES:
        return TARGET_TYPES
    return RESCUE_CLASSES


def in_type_order(types) -> list[str]:
    """``types`` in :data:`TYPES`' order, any other name after them in alphabetical order: the one
    order every table and legend lists types in.

    >>> in_type_order({"landolt-c", "qr", "hazmat", "zebra"})
    ['hazmat', 'qr', 'landolt-c', 'zebra']
    """
    present = set(types)
    return [t for t in TYPES if t in present] + sorted(present - set(TYPES))


def normalise(name: str) -> str:
    """Lower-case, trim, and map runs of spaces / ``_`` / ``-`` to one ``-``."""
    out = []
    prev_sep = False
    for ch in name.strip().lower():
        if ch in " _-\t":
            if not prev_sep and out:
                out.append("-")
            prev_sep = True
        else:
            out.append(ch)
            prev_sep = False
    return "".join(out).strip("-")


def canonical_type(name: str) -> str | None:
    """The canonical type for ``name`` (aliases accepted), or None if unknown."""
    key = normalise(name)
    if key in TYPES:
        return key
    return TYPE_ALIASES.get(key)


def canonical_label(name: str) -> str | None:
    """The canonical hazmat label for ``name`` (aliases accepted), or None."""
    key = normalise(name)
    if key in HAZMAT_LABELS:
        return key
    return LABEL_ALIASES.get(key)


def class_to_identity(class_name: str) -> tuple[str, str] | None:
    """Map a detector class name to (type, text); hazmat labels give ('hazmat', label)."""
    label = canonical_label(class_name)
    if label is not None:
        return ("hazmat", label)
    typ = canonical_type(class_name)
    if typ is None or typ == "hazmat":
        return None
    return (typ, "")


def identity_to_class(type_: str, text: str = "") -> str:
    """Inverse of :func:`class_to_identity`: the class name for a (type, text)."""
    if type_ == "hazmat":
        label = canonical_label(text)
        if label is None:
            raise ValueError(f"unknown hazmat label {text!r}; expected one of {HAZMAT_LABELS}")
        return label
    if type_ not in TYPES:
        raise ValueError(f"unknown type {type_!r}; expected one of {TYPES}")
    return type_


def display_name(type_: str, text: str = "") -> str:
    """What an operator reads: 'Oxidizer' for a hazmat, the QR text, or 'Fire extinguisher'."""
    if text:
        return text if type_ == "qr" else text.replace("-", " ").capitalize()
    if type_ == "qr":
        return "QR code"
    return DISPLAY_NAMES.get(type_, type_.replace("-", " ").capitalize())
