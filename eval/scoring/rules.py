"""Scoring rules as data: the YAML schema and its loader (docs/RULES.md, "Scoring presets").

A rules file says which kind of score it gives with ``scoring``: ``points`` (the
default when the key is absent: ex3, rmrc2025) or ``map_error`` (turtlebot).

A ``points`` rules file is a mapping with these fields (all required except ``description``,
``scoring``, the three autonomy fields, ``qr_mapping`` and ``qr_text_filter``; the two fiducial
fields exactly with ``qr_mapping: fiducials``; no others):

``name``
    A non-empty string.
``description``
    Optional free text.
``identify_radius_m``
    Pairs farther apart than this (3D distance in the map frame) are never made
    (ex3 rule 2: 2.0); ``null`` means no distance limit (rmrc2025).
``false_report_penalty``
    ``type_points`` (an unpaired report loses its type's points, ex3 rule 4) or
    ``zero`` (it only forfeits, rmrc2025).
``unscored_types``
    ``ignore``: types absent from ``types`` are not scored; their reports and
    objects are listed as ignored, never as false reports or misses.
``types``
    A mapping from canonical type name (:data:`poi.core.names.TYPES`) to a mapping with
    ``points`` (a paired report's points, >= 0), ``locate_radius_m`` (a pair this
    close or closer scores ``located_points`` instead; ``null`` = no locate bonus),
    ``located_points`` (the points of a located report, >= ``points``; ``null``
    exactly when ``locate_radius_m`` is null) and ``identity_uses_text`` (whether
    the text is part of the identity, ex3 rule 1: true for hazmat and qr).
``autonomy_multiplier``
    Optional (absent: no autonomy scoring, ex3): a number >= 1 that multiplies the points of
    a paired report whose mode is ``A`` (docs/RULES.md "Autonomy"; RMRC: 4).
``autonomy_requires_no_false_or_multiple``
    Optional, default false; only with ``autonomy_multiplier``: the multiplier applies only
    when the run has no false report and no multiple detection (a duplicate is a false report).
``qr_mapping_replaces_autonomy``
    Optional, default false; only with ``autonomy_multiplier``: ``qr`` reports are never
    multiplied (their locate bonus, the mapping bonus, takes the autonomy bonus's place).
``qr_mapping``
    Optional, default ``radius``: how a paired QR code earns ``located_points`` (the mapping
    bonus). ``radius``: within ``locate_radius_m`` of its object. ``fiducials`` ([RMRC2025]_,
    docs/RULES.md "QR mapping by fiducials"): its distances on the map to the two fiducials
    closest to it in real life are each within ``fiducial_tolerance_m`` of the true distances
    (the radius rule decides when the ground truth has fewer than two fiducials).
``fiducial_tolerance_m``, ``fiducial_match_radius_m``
    Required with ``qr_mapping: fiducials``, refused without it: the tolerance (RMRC: 0.30 m),
    and how far a reported fiducial may lie from a true one to stand for it on the map.
``qr_text_filter``
    Optional: a regular expression; only QR codes whose text matches it whole are scored (the
    others' objects and reports are ignored). The finals score only the 2 mm code: ``".* 2mm"``.
``landolt_rings``, ``landolt_radius_m``
    Required when ``types`` lists ``landolt-c`` (whose ``identity_uses_text`` must be true),
    refused otherwise ([RMRC2025]_, docs/RULES.md "Landolt-C"): the ring numbers whose gap
    directions a report must give right (1 = the outermost; RMRC Sensor Cabinet: ``[3]``,
    Linear Rail Inspect finals: ``[3, 4]``), and how far a report may lie from its target
    (metres, 3D) to pair with it.

A ``map_error`` rules file (the TurtleBot goal arena, [Bouda2025]_ section 1; scored by
eval/scoring/map_error.py) has these fields (all required except ``description``):

``name``, ``description``
    As above.
``scoring``
    ``map_error``.
``types``
    A non-empty list of canonical type names: every ground-truth object of these types
    is paired with at most one report of its type (types not listed are ignored).
``max_pair_distance_m``
    Pairs farther apart than this (2D distance in the map frame) are never made: the
    object is missed and the report false.
``goal_type``
    A type of ``types`` whose ground-truth objects, exactly two, mark the goal (its
    centre is their midpoint), or ``null`` for no goal figure.

>>> rules = load_rules("ex3")
>>> rules.identify_radius_m, rules.types["door"].points, rules.types["door"].located_points
(2.0, 5, 10)
>>> rules.max_points("qr"), rules.penalty("valve")
(2, 3)
>>> load_rules("rmrc2025").penalty("qr")
0
>>> tb = load_rules("turtlebot")
>>> tb.scoring, tb.max_pair_distance_m, tb.goal_type
('map_error', 1.0, 'pillar-blue')

References
----------
Full entries in docs/SOURCES.md.

.. [Bouda2025] M. Bouda, E. Doležal, O. Váňa, "Řešení úkolu pro TurtleBot s detekcí objektů
   a SLAM" ("A solution of the TurtleBot task with object detection and SLAM"), 2025.
.. [RMRC2025] RoboCup Rescue Rapidly Manufactured Robot Challenge rulebook, 2025.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

from poi.core.landolt import DEFAULT_N_RINGS, orientation_text, parse_orientation_text
from poi.core.loader import LoadError, Source, is_finite_number, load_yaml_file, show
from poi.core.names import TYPES

RULES_DIR = Path(__file__).resolve().parent / "rules"
PRESETS: tuple[str, ...] = ("ex3", "rmrc2025", "rmrc2026", "rmrc2026-finals", "turtlebot")
DEFAULT_RULES = "ex3"  # a trial's rules where neither --rules nor its scenario (``rules:``) names any
QR_MAPPINGS: tuple[str, ...] = ("radius", "fiducials")
SCORINGS: tuple[str, ...] = ("points", "map_error")
PENALTIES: tuple[str, ...] = ("type_points", "zero")
UNSCORED_POLICIES: tuple[str, ...] = ("ignore",)

_TOP_FIELDS = ("name", "identify_radius_m", "false_report_penalty", "unscored_types", "types")
_AUTONOMY_FIELDS = (
    "autonomy_multiplier",
    "autonomy_requires_no_false_or_multiple",
    "qr_mapping_replaces_autonomy",
)
_FIDUCIAL_FIELDS = ("fiducial_tolerance_m", "fiducial_match_radius_m")
_LANDOLT_FIELDS = ("landolt_rings", "landolt_radius_m")
_TOP_OPTIONAL = (
    "description",
    "scoring",
    *_AUTONOMY_FIELDS,
    "qr_mapping",
    *_FIDUCIAL_FIELDS,
    "qr_text_filter",
    *_LANDOLT_FIELDS,
)
_TYPE_FIELDS = ("points", "locate_radius_m", "located_points", "identity_uses_text")
_MAP_ERROR_FIELDS = ("name", "scoring", "types", "max_pair_distance_m", "goal_type")


class RulesError(LoadError):
    """A rules file that cannot be used; the message names the file and the field."""


@dataclass(kw_only=True, frozen=True)
class TypeRule:
    """How one type scores (see the module docstring for each field)."""

    points: float
    locate_radius_m: float | None
    located_points: float | None
    identity_uses_text: bool


@dataclass(kw_only=True, frozen=True)
class Rules:
    """A points preset: docs/RULES.md "Scoring presets" as data."""

    scoring: ClassVar[str] = "points"
    name: str
    identify_radius_m: float | None
    false_report_penalty: str
    unscored_types: str
    types: dict[str, TypeRule]
    description: str = ""
    autonomy_multiplier: float | None = None
    autonomy_requires_no_false_or_multiple: bool = False
    qr_mapping_replaces_autonomy: bool = False
    qr_mapping: str = "radius"
    fiducial_tolerance_m: float | None = None
    fiducial_match_radius_m: float | None = None
    qr_text_filter: str | None = None
    landolt_rings: tuple[int, ...] | None = None
    landolt_radius_m: float | None = None
    source: str = field(default="", compare=False)

    def landolt_identity(self, text: str) -> str | None:
        """The part of a Landolt-C text that is its identity: the ``landolt_rings`` as
        "3:NE 4:S", or None when the text does not parse or lacks one of them.

        >>> finals = load_rules("rmrc2026-finals")
        >>> finals.landolt_identity("1:E 2:N 3:ne 4:S 5:W"), finals.landolt_identity("1:E 3:NE")
        ('3:NE 4:S', None)
        """
        try:
            rings = parse_orientation_text(text)
        except ValueError:
            return None
        need = self.landolt_rings or ()
        if any(k not in rings for k in need):
            return None
        return orientation_text({k: rings[k] for k in need})

    def pair_radius(self, type_: str) -> float | None:
        """How far apart a report and an object of ``type_`` may be to pair: ``identify_radius_m``,
        and for a Landolt-C target at most ``landolt_radius_m`` (None: no limit)."""
        radii = [self.identify_radius_m]
        if type_ == "landolt-c":
            radii.append(self.landolt_radius_m)
        radii = [r for r in radii if r is not None]
        return min(radii) if radii else None

    def is_scored(self, type_: str | None) -> bool:
        """Whether reports and objects of ``type_`` are scored at all."""
        return type_ is not None and type_ in self.types

    def text_is_scored(self, type_: str | None, text: str) -> bool:
        """Whether a row of a scored type with ``text`` is scored: every text, except QR codes
        the preset's ``qr_text_filter`` does not match whole.

        >>> finals = load_rules("rmrc2026-finals")
        >>> finals.text_is_scored("qr", "Chart F 2mm"), finals.text_is_scored("qr", "Chart F 5mm")
        (True, False)
        """
        if type_ != "qr" or self.qr_text_filter is None:
            return True
        return re.fullmatch(self.qr_text_filter, text) is not None

    def autonomy_factor(self, type_: str) -> float:
        """What an autonomous (mode ``A``) report of ``type_`` has its points multiplied by, when
        the run earns the multiplier (docs/RULES.md "Autonomy"); 1 without autonomy scoring.

        >>> load_rules("ex3").autonomy_factor("door"), load_rules("rmrc2025").autonomy_factor("hazmat")
        (1, 4)
        >>> load_rules("rmrc2025").autonomy_factor("qr")  # the mapping bonus replaces it
        1
        """
        if self.autonomy_multiplier is None or (type_ == "qr" and self.qr_mapping_replaces_autonomy):
            return 1
        return self.autonomy_multiplier

    def penalty(self, type_: str | None) -> float:
        """Points an unpaired report of ``type_`` loses (ex3 rule 4), as a positive number.

        An unknown or unscored type loses nothing.
        """
        if self.false_report_penalty == "zero" or not self.is_scored(type_):
            return 0
        return self.types[type_].points

    def max_points(self, type_: str) -> float:
        """Points for an object of ``type_`` found and located, autonomously where the preset
        multiplies autonomy (the max_total term)."""
        rule = self.types[type_]
        return (rule.points if rule.located_points is None else rule.located_points) * self.autonomy_factor(type_)

    def to_dict(self) -> dict[str, Any]:
        """The rules as the YAML mapping they were loaded from (plus ``source``)."""
        return {
            "name": self.name,
            "description": self.description,
            "identify_radius_m": self.identify_radius_m,
            "false_report_penalty": self.false_report_penalty,
            "unscored_types": self.unscored_types,
            "types": {
                t: {
                    "points": r.points,
                    "locate_radius_m": r.locate_radius_m,
                    "located_points": r.located_points,
                    "identity_uses_text": r.identity_uses_text,
                }
                for t, r in self.types.items()
            },
            **(
                {f: getattr(self, f) for f in _AUTONOMY_FIELDS}  # only a preset that scores autonomy lists them
                if self.autonomy_multiplier is not None
                else {}
            ),
            **(
                {"qr_mapping": self.qr_mapping, **{f: getattr(self, f) for f in _FIDUCIAL_FIELDS}}
                if self.qr_mapping == "fiducials"
                else {}
            ),
            **({} if self.qr_text_filter is None else {"qr_text_filter": self.qr_text_filter}),
            **(
                {}
                if self.landolt_rings is None
                else {"landolt_rings": list(self.landolt_rings), "landolt_radius_m": self.landolt_radius_m}
            ),
            "source": self.source,
        }


@dataclass(kw_only=True, frozen=True)
class MapErrorRules:
    """A map-error preset (module docstring): how far the map puts each object."""

    scoring: ClassVar[str] = "map_error"
    name: str
    types: tuple[str, ...]
    max_pair_distance_m: float
    goal_type: str | None
    description: str = ""
    source: str = field(default="", compare=False)

    def is_scored(self, type_: str | None) -> bool:
        """Whether reports and objects of ``type_`` are paired at all."""
        return type_ is not None and type_ in self.types

    def to_dict(self) -> dict[str, Any]:
        """The rules as the YAML mapping they were loaded from (plus ``source``)."""
        return {
            "name": self.name,
            "description": self.description,
            "scoring": self.scoring,
            "types": list(self.types),
            "max_pair_distance_m": self.max_pair_distance_m,
            "goal_type": self.goal_type,
            "source": self.source,
        }


AnyRules = Rules | MapErrorRules


def trial_rules(given: str | None, scenario_rules: str | None) -> str:
    """The rules a trial is scored by: ``--rules`` where given, else its scenario's own
    (``rules:``), else :data:`DEFAULT_RULES` (``poibench run`` and every suite command alike)."""
    return given or scenario_rules or DEFAULT_RULES


def load_rules(name_or_path: str | Path) -> AnyRules:
    """Load a preset by name (one of ``PRESETS``) or a rules YAML file by path.

    Raises :class:`RulesError` naming the file and the field for anything missing or wrong.
    """
    text_name = str(name_or_path)
    if isinstance(name_or_path, str) and text_name in PRESETS:
        path = RULES_DIR / f"{text_name}.yaml"
    else:
        path = Path(name_or_path)
        if not path.is_file():
            raise RulesError(
                f"{path}: no such rules file; expected a preset name "
                f"({', '.join(PRESETS)}) or the path of a rules YAML file"
            )
    data, src = load_yaml_file(path, error=RulesError)
    return rules_from_dict(data, source=src)


def _err(source: Source, field: str, problem: str) -> RulesError:
    """``file:line: field 'types.door.points': expected ...``, the line that of the field where known."""
    return RulesError(f"{source.where(field)}: field '{field}'{problem}")


def rules_from_dict(data: Any, *, source: str | Source = "<dict>") -> AnyRules:
    """Validate a parsed rules mapping and build :class:`Rules` or :class:`MapErrorRules`
    (``source`` names it in errors; a :class:`poi.core.loader.Source` adds each field's line)."""
    source = source if isinstance(source, Source) else Source(source)
    if not isinstance(data, dict):
        raise RulesError(f"{source.name}: expected a mapping of rules fields, got {_kind(data)}")
    scoring = data.get("scoring", "points")
    if scoring not in SCORINGS:
        raise _err(source, "scoring", f": expected one of {', '.join(SCORINGS)}, got {scoring!r}")
    if scoring == "map_error":
        return _map_error_rules(data, source)
    _check_keys(data, _TOP_FIELDS, _TOP_OPTIONAL, source, where="")

    name, description = _name_and_description(data, source)
    identify = _radius(data["identify_radius_m"], source, "identify_radius_m")
    penalty = data["false_report_penalty"]
    if penalty not in PENALTIES:
        raise _err(source, "false_report_penalty", f": expected one of {', '.join(PENALTIES)}, got {penalty!r}")
    unscored = data["unscored_types"]
    if unscored not in UNSCORED_POLICIES:
        raise _err(source, "unscored_types", f": expected one of {', '.join(UNSCORED_POLICIES)}, got {unscored!r}")
    types_data = data["types"]
    if not isinstance(types_data, dict) or not types_data:
        raise _err(
            source, "types", f": expected a non-empty mapping of type name to its points, got {_kind(types_data)}"
        )
    types: dict[str, TypeRule] = {}
    for type_name, spec in types_data.items():
        if type_name not in TYPES:
            raise _err(source, f"types.{type_name}", f": unknown type; expected one of {', '.join(TYPES)}")
        types[type_name] = _type_rule(spec, source, f"types.{type_name}")
    multiplier = data.get("autonomy_multiplier")
    if multiplier is not None and (not _is_number(multiplier) or isinstance(multiplier, bool) or multiplier < 1):
        raise _err(
            source, "autonomy_multiplier", f": expected {_EXPECTED['autonomy_multiplier']}, got {show(multiplier)}"
        )
    flags: dict[str, bool] = {}
    for key in _AUTONOMY_FIELDS[1:]:
        value = data.get(key, False)
        if not isinstance(value, bool):
            raise _err(source, key, f": expected true or false, got {show(value)}")
        if value and multiplier is None:
            raise _err(source, key, ": is true but autonomy_multiplier is not set; it has nothing to act on")
        flags[key] = value
    mapping = data.get("qr_mapping", "radius")
    if mapping not in QR_MAPPINGS:
        raise _err(source, "qr_mapping", f": expected one of {', '.join(QR_MAPPINGS)}, got {show(mapping)}")
    fiducial: dict[str, float | None] = {}
    for key in _FIDUCIAL_FIELDS:
        if mapping != "fiducials":
            if key in data:
                raise _err(source, key, ": is set but qr_mapping is not 'fiducials'; it has nothing to act on")
            fiducial[key] = None
            continue
        if key not in data:
            raise _err(source, key, f" is missing; expected {_EXPECTED[key]} (qr_mapping is 'fiducials')")
        value = data[key]
        if not _is_number(value) or isinstance(value, bool) or value <= 0:
            raise _err(source, key, f": expected {_EXPECTED[key]}, got {show(value)}")
        fiducial[key] = float(value)
    if mapping == "fiducials" and ("qr" not in types or types["qr"].located_points is None):
        raise _err(source, "qr_mapping", ": is 'fiducials' but types.qr has no located_points (no mapping bonus)")
    text_filter = data.get("qr_text_filter")
    if text_filter is not None:
        if not isinstance(text_filter, str) or not text_filter:
            raise _err(source, "qr_text_filter", f": expected a regular expression, got {show(text_filter)}")
        try:
            re.compile(text_filter)
        except re.error as e:
            raise _err(source, "qr_text_filter", f": not a regular expression ({e})") from None
    landolt = _landolt_fields(data, types, source)
    return Rules(
        name=name,
        description=description,
        identify_radius_m=identify,
        false_report_penalty=penalty,
        unscored_types=unscored,
        types=types,
        autonomy_multiplier=multiplier,
        **flags,
        qr_mapping=mapping,
        **fiducial,
        qr_text_filter=text_filter,
        **landolt,
        source=source.name,
    )


def _landolt_fields(data: dict, types: dict[str, TypeRule], source: Source) -> dict[str, Any]:
    """``landolt_rings`` and ``landolt_radius_m``: required with a ``landolt-c`` type, refused without."""
    if "landolt-c" not in types:
        for key in _LANDOLT_FIELDS:
            if key in data:
                raise _err(source, key, ": is set but types has no landolt-c; it has nothing to act on")
        return {"landolt_rings": None, "landolt_radius_m": None}
    if not types["landolt-c"].identity_uses_text:
        raise _err(
            source,
            "types.landolt-c.identity_uses_text",
            ": expected true (a target is identified by its rings' gap directions)",
        )
    for key in _LANDOLT_FIELDS:
        if key not in data:
            raise _err(source, key, f" is missing; expected {_EXPECTED[key]} (types lists landolt-c)")
    rings = data["landolt_rings"]
    if (
        not isinstance(rings, list)
        or not rings
        or not all(isinstance(k, int) and not isinstance(k, bool) and 1 <= k <= DEFAULT_N_RINGS for k in rings)
        or len(set(rings)) != len(rings)
    ):
        raise _err(source, "landolt_rings", f": expected {_EXPECTED['landolt_rings']}, got {show(rings)}")
    radius = data["landolt_radius_m"]
    if not _is_number(radius) or isinstance(radius, bool) or radius <= 0:
        raise _err(source, "landolt_radius_m", f": expected {_EXPECTED['landolt_radius_m']}, got {show(radius)}")
    return {"landolt_rings": tuple(sorted(rings)), "landolt_radius_m": float(radius)}


def _name_and_description(data: dict, source: Source) -> tuple[str, str]:
    name = data["name"]
    if not isinstance(name, str) or not name.strip():
        raise _err(source, "name", f": expected a non-empty string, got {name!r}")
    description = data.get("description") or ""
    if not isinstance(description, str):
        raise _err(source, "description", f": expected a string, got {_kind(description)}")
    return name.strip(), description.strip()


def _map_error_rules(data: dict, source: Source) -> MapErrorRules:
    expected = {**_EXPECTED, "types": _EXPECTED["map_error_types"]}
    _check_keys(data, _MAP_ERROR_FIELDS, ("description",), source, where="", expected=expected)
    name, description = _name_and_description(data, source)
    types = data["types"]
    if not isinstance(types, list) or not types:
        raise _err(source, "types", f": expected {_EXPECTED['map_error_types']}, got {_kind(types)}")
    for i, t in enumerate(types):
        if t not in TYPES:
            raise _err(source, f"types[{i}]", f": unknown type {t!r}; expected one of {', '.join(TYPES)}")
    if len(set(types)) != len(types):
        raise _err(source, "types", f": expected each type once, got {types!r}")
    radius = data["max_pair_distance_m"]
    if not _is_number(radius) or radius <= 0:
        raise _err(source, "max_pair_distance_m", f": expected {_EXPECTED['max_pair_distance_m']}, got {radius!r}")
    goal = data["goal_type"]
    if goal is not None and goal not in types:
        raise _err(source, "goal_type", f": expected one of the listed types or null, got {goal!r}")
    return MapErrorRules(
        name=name,
        description=description,
        types=tuple(types),
        max_pair_distance_m=float(radius),
        goal_type=goal,
        source=source.name,
    )


def _type_rule(spec: Any, source: Source, where: str) -> TypeRule:
    if not isinstance(spec, dict):
        raise _err(source, where, f": expected a mapping with {', '.join(_TYPE_FIELDS)}, got {_kind(spec)}")
    _check_keys(spec, _TYPE_FIELDS, (), source, where=f"{where}.")
    points = _points(spec["points"], source, f"{where}.points")
    locate = _radius(spec["locate_radius_m"], source, f"{where}.locate_radius_m")
    located_raw = spec["located_points"]
    if locate is None:
        if located_raw is not None:
            raise _err(
                source,
                f"{where}.located_points",
                f": expected null when locate_radius_m is null (no locate bonus), got {located_raw!r}",
            )
        located = None
    else:
        if located_raw is None:
            raise _err(
                source,
                f"{where}.located_points",
                ": expected a number >= points when locate_radius_m is set, got null",
            )
        located = _points(located_raw, source, f"{where}.located_points")
        if located < points:
            raise _err(
                source, f"{where}.located_points", f": expected a number >= points ({points}), got {located}"
            )
    uses_text = spec["identity_uses_text"]
    if not isinstance(uses_text, bool):
        raise _err(source, f"{where}.identity_uses_text", f": expected true or false, got {uses_text!r}")
    return TypeRule(points=points, locate_radius_m=locate, located_points=located, identity_uses_text=uses_text)


def _check_keys(
    data: dict,
    required: tuple[str, ...],
    optional: tuple[str, ...],
    source: Source,
    *,
    where: str,
    expected: dict[str, str] | None = None,
) -> None:
    expected = _EXPECTED if expected is None else expected
    for key in required:
        if key not in data:
            raise _err(source, f"{where}{key}", f" is missing; expected {expected[key]}")
    for key in data:
        if key not in required and key not in optional:
            raise _err(source, f"{where}{key}", f" is unknown; expected only {', '.join(required + optional)}")


_EXPECTED: dict[str, str] = {
    "name": "a non-empty string",
    "identify_radius_m": "a distance in metres > 0, or null for no limit",
    "false_report_penalty": f"one of {', '.join(PENALTIES)}",
    "unscored_types": f"one of {', '.join(UNSCORED_POLICIES)}",
    "types": "a mapping of type name to its points",
    "points": "a number >= 0",
    "locate_radius_m": "a distance in metres > 0, or null for no locate bonus",
    "located_points": "a number >= points, or null when locate_radius_m is null",
    "identity_uses_text": "true or false",
    "scoring": f"one of {', '.join(SCORINGS)}",
    "autonomy_multiplier": "a number >= 1 (the points of an autonomous report are multiplied by it), or null",
    "map_error_types": "a non-empty list of type names",
    "fiducial_tolerance_m": "a distance in metres > 0 (RMRC: 0.30)",
    "fiducial_match_radius_m": "a distance in metres > 0 (a reported fiducial this near a true one stands for it)",
    "max_pair_distance_m": "a distance in metres > 0",
    "landolt_rings": f"a list of distinct ring numbers from 1 to {DEFAULT_N_RINGS} (1 = the outermost; RMRC: [3])",
    "landolt_radius_m": "a distance in metres > 0 (a Landolt-C report this near its target pairs with it)",
    "goal_type": "a type of 'types' (two objects of it mark the goal) or null",
}


def _is_number(value: Any) -> bool:
    return is_finite_number(value)  # NaN, +-inf and integers beyond float range are not


def _radius(value: Any, source: Source, where: str) -> float | None:
    if value is None:
        return None
    if not _is_number(value) or value <= 0:
        raise _err(source, where, f": expected a distance in metres > 0 or null, got {show(value)}")
    return float(value)


def _points(value: Any, source: Source, where: str) -> float:
    if not _is_number(value) or value < 0:
        raise _err(source, where, f": expected a finite number >= 0, got {show(value)}")
    return value


def _kind(value: Any) -> str:
    return "nothing" if value is None else f"a {type(value).__name__}"
