"""Load YAML into typed dataclasses, with errors that name the file, line and key.

A scenario (or any settings file) is composed with PyYAML's node API so every
key keeps its line number; :func:`build` then walks a dataclass's fields,
checks types and reports the first problem as one line:
``scenario.yaml:12: sensors.d435.fps: expected a number, got 'fast'``.

>>> from dataclasses import dataclass
>>> @dataclass(kw_only=True)
... class Pt:
...     x: float = 0.0
...     name: str = "a"
>>> build(Pt, {"x": 2}, Source("<doc>"))
Pt(x=2.0, name='a')
>>> build(Pt, {"y": 2}, Source("<doc>"))
Traceback (most recent call last):
...
sim.schema.SchemaError: <doc>: y: unknown key; expected one of: x, name
"""

from __future__ import annotations

import dataclasses
import types
import typing
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal, get_args, get_origin

import yaml


class SchemaError(ValueError):
    """A settings file that does not fit its schema; the message is one line."""


@dataclass
class Source:
    """Where a document came from, and the line of each dotted key in it."""

    name: str
    lines: dict[str, int] = field(default_factory=dict)

    def where(self, path: str) -> str:
        key = path
        while key:
            if key in self.lines:
                return f"{self.name}:{self.lines[key]}"
            key = key.rpartition(".")[0]
        return self.name


def _record_lines(node: yaml.Node, prefix: str, lines: dict[str, int]) -> None:
    if isinstance(node, yaml.MappingNode):
        for k, v in node.value:
            key = f"{prefix}.{k.value}" if prefix else str(k.value)
            lines[key] = k.start_mark.line + 1
            _record_lines(v, key, lines)
    elif isinstance(node, yaml.SequenceNode):
        for i, v in enumerate(node.value):
            key = f"{prefix}[{i}]"
            lines[key] = v.start_mark.line + 1
            _record_lines(v, key, lines)


def load_yaml(text: str, name: str) -> tuple[Any, Source]:
    """Parse YAML text; return the data and a :class:`Source` with key lines."""
    try:
        node = yaml.compose(text, Loader=yaml.SafeLoader)
        data = yaml.safe_load(text)
    except yaml.MarkedYAMLError as e:
        mark = e.problem_mark or e.context_mark
        line = f":{mark.line + 1}:{mark.column + 1}" if mark else ""
        raise SchemaError(f"{name}{line}: not valid YAML: {e.problem or e.context}") from None
    except yaml.YAMLError as e:
        raise SchemaError(f"{name}: not valid YAML: {e}") from None
    src = Source(name)
    if node is not None:
        _record_lines(node, "", src.lines)
    return data, src


def load_yaml_file(path: str | Path) -> tuple[Any, Source]:
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8-sig")
    except OSError as e:
        raise SchemaError(f"{p}: cannot read: {e.strerror or e}") from None
    return load_yaml(text, str(p))


def _describe(tp: Any) -> str:
    origin = get_origin(tp)
    if origin is Literal:
        return "one of " + ", ".join(repr(a) for a in get_args(tp))
    if origin in (list, tuple):
        return "a list"
    if origin is dict:
        return "a mapping"
    if origin in (typing.Union, types.UnionType):
        return " or ".join(_describe(a) for a in get_args(tp) if a is not type(None))
    if dataclasses.is_dataclass(tp):
        return "a mapping"
    return {float: "a number", int: "an integer", bool: "true or false", str: "a string"}.get(
        tp, getattr(tp, "__name__", str(tp))
    )


def _fail(src: Source, path: str, msg: str) -> SchemaError:
    return SchemaError(f"{src.where(path)}: {path or '(top)'}: {msg}")


def convert(tp: Any, value: Any, src: Source, path: str) -> Any:
    """Check ``value`` against type ``tp`` and convert it (int -> float, lists -> tuples)."""
    origin = get_origin(tp)
    if tp is Any:
        return value
    if origin in (typing.Union, types.UnionType):
        args = get_args(tp)
        if value is None and type(None) in args:
            return None
        errors = []
        for a in args:
            if a is type(None):
                continue
            try:
                return convert(a, value, src, path)
            except SchemaError as e:
                errors.append(e)
        if len(errors) == 1:  # X | None: X's own error says what is wrong, and where
            raise errors[0]
        raise _fail(src, path, f"expected {_describe(tp)}, got {value!r}")
    if origin is Literal:
        if value not in get_args(tp):
            raise _fail(src, path, f"expected {_describe(tp)}, got {value!r}")
        return value
    if origin in (list, tuple):
        if not isinstance(value, (list, tuple)):
            raise _fail(src, path, f"expected a list, got {value!r}")
        args = get_args(tp)
        if origin is tuple and args and args[-1] is not Ellipsis:
            if len(value) != len(args):
                raise _fail(src, path, f"expected a list of {len(args)} values, got {len(value)}")
            return tuple(
                convert(a, v, src, f"{path}[{i}]") for i, (a, v) in enumerate(zip(args, value, strict=True))
            )
        inner = args[0] if args else Any
        out = [convert(inner, v, src, f"{path}[{i}]") for i, v in enumerate(value)]
        return tuple(out) if origin is tuple else out
    if origin is dict:
        if not isinstance(value, dict):
            raise _fail(src, path, f"expected a mapping, got {value!r}")
        kt, vt = get_args(tp) or (Any, Any)
        return {convert(kt, k, src, path): convert(vt, v, src, f"{path}.{k}") for k, v in value.items()}
    if dataclasses.is_dataclass(tp):
        return build(tp, value, src, path)
    if tp is bool:
        if not isinstance(value, bool):
            raise _fail(src, path, f"expected true or false, got {value!r}")
        return value
    if tp is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise _fail(src, path, f"expected an integer, got {value!r}")
        return value
    if tp is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise _fail(src, path, f"expected a number, got {value!r}")
        v = float(value)
        if v != v:
            raise _fail(src, path, "expected a number, got NaN")
        return v
    if tp is str:
        if not isinstance(value, str):
            raise _fail(src, path, f"expected a string, got {value!r}")
        return value
    raise TypeError(f"schema: unsupported type {tp!r} at {path}")


def build(cls: type, data: Any, src: Source, path: str = "") -> Any:
    """Build dataclass ``cls`` from a mapping, checking every key (unknown keys refused)."""
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise _fail(src, path, f"expected a mapping, got {data!r}")
    hints = typing.get_type_hints(cls)
    fields = {f.name: f for f in dataclasses.fields(cls) if f.init}
    kwargs = {}
    for key, value in data.items():
        sub = f"{path}.{key}" if path else str(key)
        if key not in fields:
            raise _fail(src, sub, "unknown key; expected one of: " + ", ".join(fields))
        kwargs[key] = convert(hints[key], value, src, sub)
    for name, f in fields.items():
        if name not in kwargs and f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING:
            raise _fail(src, path, f"missing key {name!r} ({_describe(hints[name])})")
    try:
        obj = cls(**kwargs)
    except ValueError as e:
        raise _fail(src, path, str(e)) from None
    return obj


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
