"""The one YAML reader and YAML-to-dataclass loader of every settings file, bounded, with file:line errors.

Scenarios, pipeline configs, scoring rules, suites, calibrations and every other YAML
file the project reads go through here, so each bad input ends as one
:class:`LoadError` (a ``ValueError``; each file kind's own error class subclasses it)
of one line: ``scenario.yaml:12: sensors.d435.fps: expected a number, got 'fast'``.

Reading is bounded in time and memory whatever the input:

* at most :data:`MAX_BYTES` bytes are read; a larger file is refused with the limit named;
* the bytes must be UTF-8 (a leading byte-order mark is dropped); the first bad byte is
  named with its line and column;
* the document is composed from libyaml's parser events (PyYAML's own parser where
  libyaml is missing) by a loop, not recursion; nesting deeper than :data:`MAX_DEPTH`
  is refused there, before anything recurses on it;
* anchors and aliases (``&a``, ``*a``) are refused outright: no shipped file uses them,
  and expanding them is how a few hundred bytes ("billion laughs") become gigabytes;
* duplicate keys are refused (PyYAML silently keeps the last one), and so are merge
  keys (``<<``), keys that are not scalars and tags other than the plain ones;
* a scalar PyYAML cannot construct (an integer of more than 4300 digits, a bad
  timestamp) is refused at its line.

:func:`build` then turns a mapping into a dataclass by its type hints (nested
dataclasses, lists, tuples, dicts, ``X | None``, ``Literal``): unknown keys are refused
with the allowed ones listed, numbers must be finite (NaN, +-inf and integers beyond
float range are refused where a float is expected), and a numeric range declared once
next to the field with :func:`number` is checked. A ``__post_init__`` may raise
``ValueError`` (blamed on the mapping) or :class:`FieldError` (blamed on one field).

>>> from dataclasses import dataclass
>>> @dataclass(kw_only=True)
... class Pt:
...     x: float = number(0.0, lo=0.0)
...     name: str = "a"
>>> build(Pt, *load_yaml("x: 2\\n", "pt.yaml"))
Pt(x=2.0, name='a')
>>> build(Pt, *load_yaml("name: b\\ny: 2\\n", "pt.yaml"))
Traceback (most recent call last):
...
poi.core.loader.LoadError: pt.yaml:2: y: unknown key; expected one of x, name
>>> build(Pt, *load_yaml("x: -1\\n", "pt.yaml"))
Traceback (most recent call last):
...
poi.core.loader.LoadError: pt.yaml:1: x: expected a value >= 0, got -1
"""

from __future__ import annotations

import dataclasses
import math
import re
import reprlib
import sys
import types
import typing
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal, get_args, get_origin

import yaml
from yaml.composer import ComposerError
from yaml.scanner import ScannerError

MAX_BYTES = 256 * 1024  # larger files are refused unread; at the cap a file parses in under 1.5 s CPU (libyaml)
MAX_DEPTH = 64  # nested mappings/lists deeper than this are refused while composing

_PLAIN_TAGS = {yaml.MappingNode: "tag:yaml.org,2002:map", yaml.SequenceNode: "tag:yaml.org,2002:seq"}
_MERGE_TAG = "tag:yaml.org,2002:merge"


class LoadError(ValueError):
    """A settings file (or value) that cannot be used; the message is one line, ``file:line: field: ...``."""


class FieldError(ValueError):
    """Raised by a dataclass's ``__post_init__`` to blame ``field`` (a dotted key relative to it)."""

    def __init__(self, field: str, message: str) -> None:
        super().__init__(message)
        self.field = field


@dataclass
class Source:
    """Where a document came from, and the line of each dotted key in it (``a.b[0].c``)."""

    name: str
    lines: dict[str, int] = field(default_factory=dict)

    def where(self, path: str) -> str:
        """``name:line`` of ``path`` or of its nearest enclosing key with a line, else ``name``."""
        key = path
        while key:
            if key in self.lines:
                return f"{self.name}:{self.lines[key]}"
            cut = max(key.rfind("."), key.rfind("["))
            key = key[:cut] if cut > 0 else ""
        return self.name


_SHOW = reprlib.Repr()
_SHOW.maxstring = 60
_SHOW.maxother = 60
_SHOW.maxlist = _SHOW.maxtuple = _SHOW.maxdict = 6
_SHOW.maxlevel = 3


def show(value: Any) -> str:
    """A short one-line repr of a value for an error message (long strings and numbers cut)."""
    if isinstance(value, int) and not isinstance(value, bool) and value.bit_length() > 128:
        return f"an integer of {value.bit_length()} bits"
    return _SHOW.repr(value)


# ---------------------------------------------------------------------------------------------
# Reading


def decode(raw: bytes, name: str, *, error: type[ValueError] = LoadError) -> str:
    """UTF-8 bytes to text (a byte-order mark dropped); a bad byte is named with its line and column."""
    if len(raw) > MAX_BYTES:
        raise error(f"{name}: {len(raw)} bytes, over the {MAX_BYTES // 1024} KiB limit on settings files")
    body = raw[3:] if raw.startswith(b"\xef\xbb\xbf") else raw
    try:
        return body.decode("utf-8")
    except UnicodeDecodeError as e:
        line = body.count(b"\n", 0, e.start) + 1
        col = e.start - (body.rfind(b"\n", 0, e.start) + 1) + 1
        raise error(f"{name}:{line}:{col}: not UTF-8 text: byte 0x{body[e.start]:02x} ({e.reason})") from None


def read_text(path: str | Path, *, what: str = "", error: type[ValueError] = LoadError) -> str:
    """The text of a settings file, at most :data:`MAX_BYTES` of UTF-8 (``what`` names it in errors)."""
    p = Path(path)
    try:
        with p.open("rb") as f:
            raw = f.read(MAX_BYTES + 1)
    except OSError as e:
        raise error(f"{p}: cannot read{' ' + what if what else ''}: {e.strerror or e}") from None
    return decode(raw, str(p), error=error)


# A number in exponent notation without a decimal point (1e6, 2E-3): YAML 1.1, which PyYAML
# follows, resolves it to a string, YAML 1.2's core schema to a float. A float field takes it.
_EXPONENT_FLOAT = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)[eE][-+]?\d+")


class _BoundedLoader(yaml.SafeLoader):
    """PyYAML's pure-Python safe loader with a depth limit in its scanner (used without libyaml).

    The scanner looks ahead over a run of ``[`` or ``{`` for a possible key, checking
    every open level at each token (quadratic in their number), so it must stop at the
    limit itself, before the composer sees a single event.
    """

    def _too_deep(self) -> ScannerError:
        return ScannerError(None, None, f"nested more than {MAX_DEPTH} levels deep", self.get_mark())

    def fetch_flow_collection_start(self, TokenClass: Any) -> None:  # the base's parameter name
        if self.flow_level >= MAX_DEPTH:
            raise self._too_deep()
        super().fetch_flow_collection_start(TokenClass)

    def add_indent(self, column: int) -> bool:
        if len(self.indents) >= MAX_DEPTH:
            raise self._too_deep()
        return super().add_indent(column)


# libyaml's C parser where PyYAML has it (about 10x faster than its pure-Python parser)
_PARSER: type = getattr(yaml, "CSafeLoader", _BoundedLoader) if yaml.__with_libyaml__ else _BoundedLoader


def _refuse(msg: str, mark: Any) -> ComposerError:
    return ComposerError(None, None, msg, mark)


# the node a collection's start event opens
_COLLECTIONS: dict[type, type[yaml.SequenceNode] | type[yaml.MappingNode]] = {
    yaml.SequenceStartEvent: yaml.SequenceNode,
    yaml.MappingStartEvent: yaml.MappingNode,
}


def _compose_events(loader: Any) -> yaml.Node | None:
    """The single document's node tree, composed from the parser's events without recursion.

    As PyYAML's Composer (tags resolved the same way), but refusing anchors and aliases
    and nesting deeper than :data:`MAX_DEPTH`.
    """
    loader.get_event()  # StreamStart
    if loader.check_event(yaml.StreamEndEvent):
        return None
    loader.get_event()  # DocumentStart
    stack: list[yaml.CollectionNode] = []
    keys: list[yaml.Node | None] = []  # per open mapping: its key waiting for a value
    root = None
    while root is None:
        event = loader.get_event()
        if isinstance(event, yaml.AliasEvent):
            raise _refuse("aliases (*name) are not allowed", event.start_mark)
        if isinstance(event, yaml.CollectionEndEvent):
            node = stack.pop()
            keys.pop()
            node.end_mark = event.end_mark
        else:
            if event.anchor is not None:
                raise _refuse("anchors (&name) are not allowed", event.start_mark)
            if len(stack) >= MAX_DEPTH:
                raise _refuse(f"nested more than {MAX_DEPTH} levels deep", event.start_mark)
            scalar = isinstance(event, yaml.ScalarEvent)
            collection = None if scalar else _COLLECTIONS[type(event)]
            kind = yaml.ScalarNode if collection is None else collection
            tag = event.tag
            if tag is None or tag == "!":
                tag = loader.resolve(kind, event.value if scalar else None, event.implicit)
            if collection is None:
                node = yaml.ScalarNode(tag, event.value, event.start_mark, event.end_mark, style=event.style)
            else:
                stack.append(collection(tag, [], event.start_mark, None, flow_style=event.flow_style))
                keys.append(None)
                continue
        if not stack:
            root = node
        elif isinstance(stack[-1], yaml.SequenceNode):
            stack[-1].value.append(node)
        elif keys[-1] is None:
            keys[-1] = node
        else:
            stack[-1].value.append((keys[-1], node))
            keys[-1] = None
    loader.get_event()  # DocumentEnd
    if not loader.check_event(yaml.StreamEndEvent):
        event = loader.get_event()
        raise ComposerError(
            "expected a single document in the stream",
            root.start_mark,
            "but found another document",
            event.start_mark,
        )
    return root


def _line_of(text: str, position: int) -> int:
    return text.count("\n", 0, max(position, 0)) + 1


def _compose(text: str, name: str, error: type[ValueError]) -> tuple[yaml.Node | None, Any]:
    if len(text) > MAX_BYTES or len(text.encode("utf-8", "surrogatepass")) > MAX_BYTES:
        raise error(f"{name}: over the {MAX_BYTES // 1024} KiB limit on settings files")
    try:
        text.encode("utf-8")
    except UnicodeEncodeError as e:  # a lone surrogate: a byte of no UTF-8 text (argv's surrogateescape)
        c = ord(text[e.start])
        what = f"byte 0x{c - 0xDC00:02x}" if 0xDC80 <= c <= 0xDCFF else f"character U+{c:04X}"
        raise error(f"{name}:{_line_of(text, e.start)}: not UTF-8 text: {what}") from None
    try:
        loader = _PARSER(text)
        try:
            return _compose_events(loader), loader
        finally:
            loader.dispose()
    except yaml.MarkedYAMLError as e:
        mark = e.problem_mark or e.context_mark
        at = f":{mark.line + 1}:{mark.column + 1}" if mark else ""
        raise error(f"{name}{at}: not valid YAML: {e.problem or e.context}") from None
    except yaml.reader.ReaderError as e:
        char = f" #x{e.character:04x}" if isinstance(e.character, int) else ""
        raise error(f"{name}:{_line_of(text, e.position)}: not valid YAML: {e.reason}{char}") from None
    except yaml.YAMLError as e:
        first = str(e).splitlines()[0] if str(e) else type(e).__name__
        raise error(f"{name}: not valid YAML: {first}") from None


def _to_data(
    node: yaml.Node, ctor: yaml.SafeLoader, path: str, lines: dict[str, int], name: str, error: type[ValueError]
) -> Any:
    """Plain Python data from a composed node (depth <= MAX_DEPTH), recording each key's line."""

    def fail(n: yaml.Node, msg: str) -> ValueError:
        return error(f"{name}:{n.start_mark.line + 1}: {path or '(top)'}: {msg}")

    if isinstance(node, yaml.ScalarNode):
        try:
            value = ctor.construct_object(node, deep=True)
            if isinstance(value, int):
                str(value)  # a hex/octal integer past Python's 4300-digit limit cannot even be printed
            return value
        except (yaml.YAMLError, ValueError, OverflowError) as e:
            reason = getattr(e, "problem", None) or str(e).splitlines()[0]
            if "integer string conversion" in reason:
                reason = f"an integer of more than {sys.get_int_max_str_digits()} digits"
            raise fail(node, f"cannot read {show(node.value)}: {reason[:100]}") from None
        except (LookupError, AttributeError):
            # PyYAML's constructors index or match an explicitly tagged odd scalar without checking
            # (!!int '' and !!int +: IndexError, !!bool x: KeyError, !!timestamp x: AttributeError)
            raise fail(node, f"cannot read {show(node.value)} as {node.tag.rpartition(':')[2]}") from None
    if node.tag != _PLAIN_TAGS[type(node)]:
        raise fail(node, f"tag {node.tag!r} is not supported")
    if isinstance(node, yaml.SequenceNode):
        out = []
        for i, item in enumerate(node.value):
            sub = f"{path}[{i}]"
            lines[sub] = item.start_mark.line + 1
            out.append(_to_data(item, ctor, sub, lines, name, error))
        return out
    mapping: dict[Any, Any] = {}
    for key_node, value_node in node.value:
        if key_node.tag == _MERGE_TAG:
            raise fail(key_node, "merge keys (<<) are not supported")
        if not isinstance(key_node, yaml.ScalarNode):
            raise fail(key_node, "expected a plain key (a string or number), got a mapping or list")
        key = _to_data(key_node, ctor, path, lines, name, error)
        sub = f"{path}.{key}" if path else str(key)
        try:
            seen = key in mapping
        except TypeError:
            raise fail(key_node, f"key {show(key)} cannot be used as a key") from None
        if seen:
            first = lines.get(sub, "?")
            raise error(
                f"{name}:{key_node.start_mark.line + 1}: {sub}: duplicate key (first given on line {first})"
            )
        lines[sub] = key_node.start_mark.line + 1
        mapping[key] = _to_data(value_node, ctor, sub, lines, name, error)
    return mapping


def load_yaml(text: str, name: str, *, error: type[ValueError] = LoadError) -> tuple[Any, Source]:
    """Parse YAML text (bounded, see the module docstring); return the data and a :class:`Source`."""
    node, loader = _compose(text, name, error)
    src = Source(name)
    if node is None:
        return None, src
    return _to_data(node, loader, "", src.lines, name, error), src


def load_yaml_file(path: str | Path, *, what: str = "", error: type[ValueError] = LoadError) -> tuple[Any, Source]:
    """:func:`read_text` then :func:`load_yaml`, named by the path."""
    return load_yaml(read_text(path, what=what, error=error), str(path), error=error)


def safe_load(text: str, name: str = "<yaml>", *, error: type[ValueError] = LoadError) -> Any:
    """``yaml.safe_load``, bounded (see the module docstring), errors as :class:`LoadError`."""
    return load_yaml(text, name, error=error)[0]


def safe_load_file(path: str | Path, *, what: str = "", error: type[ValueError] = LoadError) -> Any:
    """The data of a YAML file, read with :func:`load_yaml_file`."""
    return load_yaml_file(path, what=what, error=error)[0]


# ---------------------------------------------------------------------------------------------
# Numbers and ranges


def is_finite_number(value: Any) -> bool:
    """A number (not a bool) that is finite as a float: NaN, +-inf and ints beyond float range are not.

    >>> is_finite_number(3), is_finite_number(float("inf")), is_finite_number(10**400), is_finite_number(True)
    (True, False, False, False)
    """
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return False
    try:
        return math.isfinite(value)
    except OverflowError:
        return False


@dataclass(frozen=True)
class Range:
    """Allowed values ``lo <= v <= hi`` (an end of None is open; ``lo_open``/``hi_open`` make it strict)."""

    lo: float | None = None
    hi: float | None = None
    lo_open: bool = False
    hi_open: bool = False

    def contains(self, v: float) -> bool:
        if self.lo is not None and (v <= self.lo if self.lo_open else v < self.lo):
            return False
        return not (self.hi is not None and (v >= self.hi if self.hi_open else v > self.hi))

    def describe(self) -> str:
        """``> 0 and <= 1``."""
        lo = "" if self.lo is None else f"{'>' if self.lo_open else '>='} {self.lo:g}"
        hi = "" if self.hi is None else f"{'<' if self.hi_open else '<='} {self.hi:g}"
        return " and ".join(t for t in (lo, hi) if t)


def number(
    default: Any = dataclasses.MISSING,
    *,
    lo: float | None = None,
    hi: float | None = None,
    lo_open: bool = False,
    hi_open: bool = False,
) -> Any:
    """A dataclass field whose number (or each number of its tuple or list) must lie in a range."""
    return field(default=default, metadata={"range": Range(lo, hi, lo_open, hi_open)})


def _check_range(rng: Range, value: Any, given: Any) -> str | None:
    """Why ``value`` (converted from ``given``; a number, or a tuple or list of them) is out of range."""
    if value is None:
        return None
    values = value if isinstance(value, (tuple, list)) else (value,)
    for v in values:
        if is_finite_number(v) and not rng.contains(v):
            return f"expected a value {rng.describe()}, got {show(given)}"
    return None


# ---------------------------------------------------------------------------------------------
# Dataclasses from data


def describe(tp: Any) -> str:
    """What a value of type ``tp`` looks like, in words (``a number``, ``one of 'a', 'b'``)."""
    origin = get_origin(tp)
    if origin is Literal:
        return "one of " + ", ".join(repr(a) for a in get_args(tp))
    if origin in (list, tuple) or tp in (list, tuple):
        return "a list"
    if origin is dict or tp is dict or dataclasses.is_dataclass(tp):
        return "a mapping"
    if origin in (typing.Union, types.UnionType):
        return " or ".join("null" if a is type(None) else describe(a) for a in get_args(tp))
    return {float: "a number", int: "an integer", bool: "true or false", str: "a string"}.get(
        tp, getattr(tp, "__name__", str(tp))
    )


def _fail(src: Source, path: str, msg: str) -> LoadError:
    return LoadError(f"{src.where(path)}: {path or '(top)'}: {msg}")


def _convert(tp: Any, value: Any, src: Source, path: str) -> Any:
    """``value`` checked against type ``tp`` and converted; a LoadError naming ``path`` if it does not fit."""
    origin = get_origin(tp)
    if tp is Any:
        return value
    if origin in (typing.Union, types.UnionType):
        return _convert_union(tp, value, src, path)
    if origin is Literal:
        if not any(value == a and type(value) is type(a) for a in get_args(tp)):
            raise _fail(src, path, f"expected {describe(tp)}, got {show(value)}")
        return value
    if origin in (list, tuple) or tp in (list, tuple):
        return _convert_sequence(tp, value, src, path)
    if origin is dict or tp is dict:
        return _convert_mapping(tp, value, src, path)
    if isinstance(tp, type) and dataclasses.is_dataclass(tp):
        return _build(tp, value, src, path)
    return _convert_scalar(tp, value, src, path)


def _convert_union(tp: Any, value: Any, src: Source, path: str) -> Any:
    """``X | Y | None``: the first of its types ``value`` fits."""
    args = get_args(tp)
    if value is None and type(None) in args:
        return None
    errors = []
    for a in args:
        if a is type(None):
            continue
        try:
            return _convert(a, value, src, path)
        except LoadError as e:
            errors.append(e)
    if len(errors) == 1:  # X | None: X's own error says what is wrong, and where
        raise errors[0]
    raise _fail(src, path, f"expected {describe(tp)}, got {show(value)}")


def _convert_sequence(tp: Any, value: Any, src: Source, path: str) -> Any:
    """A list, or a tuple of fixed length (``tuple[float, float]``) or of any (``tuple[X, ...]``)."""
    origin = get_origin(tp)
    if not isinstance(value, (list, tuple)):
        raise _fail(src, path, f"expected a list, got {show(value)}")
    args = get_args(tp)
    if (origin is tuple or tp is tuple) and args and args[-1] is not Ellipsis:
        if len(value) != len(args):
            what = "numbers" if all(a in (int, float) for a in args) else "values"
            raise _fail(src, path, f"expected a list of {len(args)} {what}, got {show(value)}")
        return tuple(_convert(a, v, src, f"{path}[{i}]") for i, (a, v) in enumerate(zip(args, value, strict=True)))
    inner = args[0] if args else Any
    out = [_convert(inner, v, src, f"{path}[{i}]") for i, v in enumerate(value)]
    return tuple(out) if (origin is tuple or tp is tuple) else out


def _convert_mapping(tp: Any, value: Any, src: Source, path: str) -> dict:
    """A mapping, each key and value converted (``dict[str, X]``)."""
    if not isinstance(value, dict):
        raise _fail(src, path, f"expected a mapping, got {show(value)}")
    kt, vt = get_args(tp) or (Any, Any)
    out_d = {}
    for k, v in value.items():
        sub = f"{path}.{k}" if path else str(k)
        if kt is str and not isinstance(k, str):
            raise _fail(src, sub, f"expected a string key, got {show(k)}")
        out_d[_convert(kt, k, src, sub)] = _convert(vt, v, src, sub)
    return out_d


def _convert_scalar(tp: Any, value: Any, src: Source, path: str) -> Any:
    """A bool, an int, a finite float (an int or an exponent string taken) or a str."""
    if tp is bool:
        if not isinstance(value, bool):
            raise _fail(src, path, f"expected true or false, got {show(value)}")
        return value
    if tp is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise _fail(src, path, f"expected an integer, got {show(value)}")
        return value
    if tp is float:
        if isinstance(value, str) and _EXPONENT_FLOAT.fullmatch(value.strip()):
            value = float(value)  # YAML 1.1 reads 1e6 as a string; YAML 1.2 and people, as a number
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise _fail(src, path, f"expected a number, got {show(value)}")
        if not is_finite_number(value):
            raise _fail(src, path, f"expected a finite number, got {show(value)}")
        return float(value)
    if tp is str:
        if not isinstance(value, str):
            raise _fail(src, path, f"expected a string, got {show(value)}")
        return value
    raise TypeError(f"loader: unsupported type {tp!r} at {path}")


def _build(cls: type, data: Any, src: Source, path: str) -> Any:
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise _fail(src, path, f"expected a mapping, got {show(data)}")
    hints = typing.get_type_hints(cls)
    fields = {f.name: f for f in dataclasses.fields(cls) if f.init}
    kwargs = {}
    for key, value in data.items():
        sub = f"{path}.{key}" if path else str(key)
        if key not in fields:
            raise _fail(src, sub, "unknown key; expected one of " + ", ".join(fields))
        kwargs[key] = _convert(hints[key], value, src, sub)
        rng = fields[key].metadata.get("range")
        bad = _check_range(rng, kwargs[key], value) if rng is not None else None
        if bad:
            raise _fail(src, sub, bad)
    for name, f in fields.items():
        if name not in kwargs and f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING:
            raise _fail(src, path, f"missing key {name!r} ({describe(hints[name])})")
    try:
        return cls(**kwargs)
    except FieldError as e:
        sub = f"{path}.{e.field}" if path else e.field
        raise _fail(src, sub, str(e)) from None
    except LoadError:
        raise
    except ValueError as e:
        raise _fail(src, path, str(e)) from None


def convert(tp: Any, value: Any, src: Source, path: str = "", *, error: type[ValueError] = LoadError) -> Any:
    """Check ``value`` against type ``tp`` and convert it (int -> float, lists -> tuples)."""
    try:
        return _convert(tp, value, src, path)
    except LoadError as e:
        raise (e if isinstance(e, error) else error(str(e))) from None


def build(cls: type, data: Any, src: Source, path: str = "", *, error: type[ValueError] = LoadError) -> Any:
    """Build dataclass ``cls`` from a mapping (null: all defaults), checking every key, type and range."""
    try:
        return _build(cls, data, src, path)
    except LoadError as e:
        raise (e if isinstance(e, error) else error(str(e))) from None


def to_plain(obj: Any) -> Any:
    """Dataclasses/tuples/numpy scalars to plain YAML-safe Python values."""
    if dataclasses.is_dataclass(obj):
        return {f.name: to_plain(getattr(obj, f.name)) for f in dataclasses.fields(obj)}
    if isinstance(obj, (list, tuple)):
        return [to_plain(v) for v in obj]
    if isinstance(obj, dict):
        return {str(k): to_plain(v) for k, v in obj.items()}
    if hasattr(obj, "item") and not isinstance(obj, (str, bytes)):
        return obj.item()
    return obj
