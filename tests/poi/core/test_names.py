"""Type and class names: the rescue ones keep their order (file formats, class indices, trained
models depend on it), the arena's are appended, parse with their aliases and read well."""

from __future__ import annotations

import pytest

from poi.core.names import (
    ARENA_TYPES,
    CLASS_INDEX,
    CLASSES,
    MAPPING_TYPES,
    RESCUE_CLASSES,
    RESCUE_TYPES,
    TARGET_TYPES,
    TYPES,
    canonical_type,
    class_to_identity,
    display_name,
    identity_to_class,
)
from poi.detectors.base import canonical_class, one_class_probs

# As they were before the arena was added, spelled out: nothing may move.
RESCUE_TYPES_V1 = [
    *("hazmat", "qr", "door", "valve", "baby-doll", "fire-extinguisher", "exit-sign"),
    *("fire-extinguisher-sign", "heat-source"),
]


def test_rescue_types_and_classes_come_first_in_their_order():
    assert list(RESCUE_TYPES) == RESCUE_TYPES_V1
    assert TYPES == RESCUE_TYPES + ARENA_TYPES + MAPPING_TYPES + TARGET_TYPES
    assert TARGET_TYPES == ("landolt-c",) and CLASSES[-1] == "landolt-c"  # its own class domain
    assert MAPPING_TYPES == ("fiducial",) and "fiducial" not in CLASSES  # a landmark, not a detector class
    assert ARENA_TYPES == ("pillar-blue", "pillar-red", "pillar-green", "ball")
    assert len(RESCUE_CLASSES) == 24 and CLASSES[:24] == RESCUE_CLASSES
    assert CLASSES[24:28] == ARENA_TYPES  # class = type for the arena
    assert RESCUE_CLASSES[16:] == tuple(RESCUE_TYPES_V1[1:])  # 16 hazmat labels, then the 8 others
    assert all(CLASS_INDEX[c] == i for i, c in enumerate(RESCUE_CLASSES))


@pytest.mark.parametrize(
    ("written", "type_"),
    [
        ("pillar-blue", "pillar-blue"),
        ("Pillar_Red", "pillar-red"),
        ("green pillar", "pillar-green"),
        ("Blue-Pillar", "pillar-blue"),
        ("BALL", "ball"),
        ("yellow ball", "ball"),
        ("football", "ball"),
    ],
)
def test_arena_types_parse_with_aliases(written, type_):
    assert canonical_type(written) == type_
    assert class_to_identity(written) == (type_, "")
    assert canonical_class(written) == type_  # an ONNX model's names map by name
    assert identity_to_class(type_) == type_


def test_display_names():
    assert [display_name(t) for t in ARENA_TYPES] == ["Blue pillar", "Red pillar", "Green pillar", "Ball"]
    assert display_name("fire-extinguisher") == "Fire extinguisher"  # unchanged for the rescue types


def test_class_probabilities_cover_every_class():
    p = one_class_probs("pillar-green", 0.9)
    assert p.shape == (len(CLASSES),) and p[CLASS_INDEX["pillar-green"]] == pytest.approx(0.9)
    assert p.sum() == pytest.approx(1.0)
