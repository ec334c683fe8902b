"""MkDocs hook: the reference pages' tables, generated from the code at build time.

A page holds a marker comment where a generated part goes:

- ``<!-- generated: pipeline-config -->``: every key of the pipeline's settings
  (``poi.config.PipelineConfig``), its type, default and range from the dataclasses, and its
  meaning from the comment above it in ``poi/configs/default.yaml`` (the file the pipeline loads
  its defaults from, documented key by key), else from the comment beside the field in
  ``poi/config.py``;
- ``<!-- generated: scenario -->``: every key of a scenario file (``sim.scenario.Scenario``),
  its type, default and range, and its meaning from the comment beside or above the field in
  its settings class (``sim/scenario.py`` and the classes it composes, each beside its model:
  ``sim/sensors/``, ``sim/world/``, ``sim/motion/``; a nested section's docstring heads its table);
- ``<!-- generated: rules -->``: the keys of a points rules file (``eval.scoring.rules.Rules``);
- ``<!-- generated: cli -->``: every ``poibench`` command's ``--help``, from its argparse parser;
- ``<!-- generated: where-it-stands -->``: the README's "Where it stands" table of today's figures
  (its lead paragraph and table), so the site's results page and the README cannot disagree.

Nothing is copied by hand, so a key added, renamed or given a new range shows on the next build.
The functions are plain Python; ``tests/test_docs_site.py`` calls them as well.

The keys' tables (``pipeline-config``, ``scenario``, ``rules``) are also kept in the Markdown
files themselves, between their marker and ``<!-- end generated -->``, so that the pages read on a
forge or in a checkout show them: ``python docs/hooks/reference.py`` writes them there, ``--check``
lists the pages whose tables are out of date (a test runs it). The commands' ``--help`` and the
README's table are put in at build time only (``poibench COMMAND --help`` prints the one; the
README holds the other).
"""

from __future__ import annotations

import dataclasses
import inspect
import io
import re
import sys
import tokenize
import types
import typing
from pathlib import Path
from typing import Any, Literal, get_args, get_origin

ROOT = Path(__file__).resolve().parents[2]
if str(ROOT) not in sys.path:  # the packages, when mkdocs runs from a checkout that is not installed
    sys.path.insert(0, str(ROOT))

# a marker, and the part generated after it up to its end marker where the page keeps one
MARKER = re.compile(
    r"<!-- generated: ([a-z-]+) -->(?:\n(?:(?!<!-- generated: ).)*?<!-- end generated -->)?", flags=re.S
)
END = "<!-- end generated -->"
KEPT_IN_PAGES = ("pipeline-config", "scenario", "rules")  # written into the Markdown files too
DOCS = ROOT / "docs"


# ---------------------------------------------------------------------------------------------
# Comments: where a key's meaning is written


def yaml_key_comments(text: str) -> dict[str, str]:
    """The comment block right above each key of a YAML file (and a comment after its value),
    by dotted key.

    >>> yaml_key_comments("# the tracker\\ntracker:\\n  # gate, m^2\\n  gate: 9  # strict\\n  n: 3\\n\\n  t: 1\\n")
    {'tracker': 'the tracker', 'tracker.gate': 'gate, m^2 strict', 'tracker.n': 'gate, m^2', 'tracker.t': ''}
    """
    out: dict[str, str] = {}
    stack: list[tuple[int, str]] = []  # (indent, key) of the open mappings
    pending: list[str] = []
    group = ""  # the comment of the keys just above, with no blank line between
    for line in text.splitlines():
        stripped = line.strip()
        if not stripped:
            pending, group = [], ""
            continue
        if stripped.startswith("#"):
            pending.append(stripped.lstrip("#").strip())
            continue
        m = re.match(r"^( *)([A-Za-z_][\w-]*):(.*)$", line)
        if not m:  # a continued flow list
            pending = []
            continue
        indent, key, rest = len(m.group(1)), m.group(2), m.group(3)
        while stack and stack[-1][0] >= indent:
            stack.pop()
        dotted = ".".join([k for _, k in stack] + [key])
        trailing = rest.split(" #", 1)[1].strip() if " #" in rest else ""
        own = " ".join(pending)
        group = own or group  # a key without its own comment shares the one of the keys above it
        out[dotted] = " ".join(t for t in (group, trailing) if t)
        pending = []
        if not rest.split("#", 1)[0].strip():  # a mapping opens
            stack.append((indent, key))
    return out


def field_comments(cls: type) -> dict[str, str]:
    """The comments of a dataclass's fields in its source: the lines right above a field and
    the one beside it."""
    try:
        source = inspect.getsource(cls)
    except (OSError, TypeError):
        return {}
    out: dict[str, str] = {}
    pending: list[str] = []
    current: str | None = None
    current_line = -1
    depth = 0
    for tok in tokenize.generate_tokens(io.StringIO(source).readline):
        if tok.type == tokenize.OP and tok.string in "([{":
            depth += 1
        elif tok.type == tokenize.OP and tok.string in ")]}":
            depth -= 1
        elif tok.type == tokenize.COMMENT:
            text = tok.string.lstrip("#").strip()
            if current is not None and tok.start[0] == current_line:
                out[current] = " ".join(t for t in (out.get(current, ""), text) if t)
            elif depth == 0:
                pending.append(text)
        elif (
            tok.type == tokenize.NAME
            and depth == 0
            and tok.start[1] == 4
            and tok.line.strip().startswith(tok.string + ":")
        ):
            current, current_line = tok.string, tok.start[0]
            out[current] = " ".join(pending)
            pending = []
        elif tok.type == tokenize.NL and tok.line.strip() == "":
            pending = []
        elif tok.type == tokenize.NAME and tok.string == "def" and depth == 0:
            break
    return out


# ---------------------------------------------------------------------------------------------
# Dataclasses into rows


@dataclasses.dataclass
class Row:
    key: str
    kind: str
    default: str
    range: str
    meaning: str


def dataclass_in(tp: Any) -> type | None:
    """The dataclass a field's type holds (``X``, ``X | None`` or ``dict[str, X]``), else None."""
    if dataclasses.is_dataclass(tp):
        return tp
    if get_origin(tp) is dict and dataclasses.is_dataclass(get_args(tp)[1]):
        return get_args(tp)[1]
    if get_origin(tp) in (typing.Union, types.UnionType):
        for a in get_args(tp):
            if dataclasses.is_dataclass(a):
                return a
    return None


def _kind_of(tp: Any, sub: type) -> str:
    return f"a mapping of {sub.__name__} rows" if get_origin(tp) is dict else f"a mapping ({sub.__name__}) or null"


def describe_type(tp: Any) -> str:
    """A field's type in words, with the loader's own description of it."""
    from poi.core.loader import describe

    if get_origin(tp) is Literal:
        return " or ".join(f"`{a}`" for a in get_args(tp))
    text = describe(tp)
    return text.replace("one of ", "")


def show_value(value: Any) -> str:
    import yaml

    if value is None:
        return "`null`"
    if dataclasses.is_dataclass(value):
        return "(section)"
    if isinstance(value, tuple):
        value = list(value)
    if isinstance(value, dict) and any(dataclasses.is_dataclass(v) for v in value.values()):
        # a table of rows (localize.types): each row's settings that are not its defaults
        value = {k: _row_settings(v) for k, v in value.items()}
    text = yaml.safe_dump(value, default_flow_style=True, width=10_000, sort_keys=False).strip()
    text = text.removesuffix("...").strip()
    return f"`{text}`"


def _row_settings(row: Any) -> dict[str, Any]:
    """A row's settings that differ from its class's defaults (the key that must be given, kept)."""
    out = {}
    for f in dataclasses.fields(row):
        value, default = getattr(row, f.name), default_of(f)
        if value != default or f.name == "shape":
            out[f.name] = value
    return out


def default_of(f: dataclasses.Field) -> Any:
    if f.default is not dataclasses.MISSING:
        return f.default
    if f.default_factory is not dataclasses.MISSING:
        return f.default_factory()
    return dataclasses.MISSING


def cell(text: str) -> str:
    """Text safe in a Markdown table cell: pipes escaped, reST's double backquotes single."""
    text = re.sub(r"``([^`]+)``", r"`\1`", text)
    text = re.sub(r"\[([A-Za-z][\w-]+)\]_", r"[\1]", text)
    return text.replace("|", "\\|").strip()


def walk(cls: type, prefix: str, yaml_comments: dict[str, str]) -> list[tuple[str, type, list[Row]]]:
    """One (dotted section, dataclass, rows) per dataclass in ``cls``, depth first; a row per
    field that is not itself a section."""
    hints = typing.get_type_hints(cls)
    comments = field_comments(cls)
    rows: list[Row] = []
    nested: list[tuple[str, type, list[Row]]] = []
    for f in dataclasses.fields(cls):
        if not f.init or f.name == "source_dir":
            continue
        key = f"{prefix}{f.name}"
        tp = hints[f.name]
        sub = dataclass_in(tp)
        if sub is not None:
            nested += walk(sub, key + (".<type>." if get_origin(tp) is dict else "."), yaml_comments)
            if dataclasses.is_dataclass(tp):
                continue  # an always-present section: its own table
        rng = f.metadata.get("range")
        default = default_of(f)
        meaning = yaml_comments.get(key) or comments.get(f.name, "")
        if not meaning and f"``{f.name}``" in (inspect.getdoc(cls) or ""):
            meaning = "(the section's text above)"
        rows.append(
            Row(
                key=key,
                kind=describe_type(tp) if sub is None else _kind_of(tp, sub),
                default="required" if default is dataclasses.MISSING else show_value(default),
                range=rng.describe() if rng is not None and rng.describe() else "",
                meaning=meaning,
            )
        )
    return [(prefix.rstrip("."), cls, rows), *nested]


def tables(cls: type, yaml_comments: dict[str, str] | None = None, top: str = "(top level)") -> str:
    """Markdown: per section, its docstring (or YAML comment) and a table of its keys."""
    yaml_comments = yaml_comments or {}
    out = []
    for section, sub, rows in walk(cls, "", yaml_comments):
        if not rows:
            continue
        out.append(f"### `{section}`\n" if section else f"### {top}\n")
        intro = yaml_comments.get(section, "") if section else ""
        doc = (inspect.getdoc(sub) or "").split("\nReferences\n", 1)[0]  # numpydoc's citations list: not here
        doc = "\n".join(line for line in doc.splitlines() if not re.fullmatch(r"\s*[-=]{3,}\s*", line))
        if doc and not doc.startswith(sub.__name__ + "("):  # a dataclass's generated signature is no docstring
            intro = " ".join(t for t in (intro, doc) if t)
        if intro:
            out.append(cell(intro).replace("\\|", "|") + "\n")
        out.append("| key | type | default | range | meaning |")
        out.append("| --- | --- | --- | --- | --- |")
        for r in rows:
            out.append(f"| `{r.key}` | {cell(r.kind)} | {cell(r.default)} | {cell(r.range)} | {cell(r.meaning)} |")
        out.append("")
    return "\n".join(out)


# ---------------------------------------------------------------------------------------------
# The generated parts


def pipeline_config() -> str:
    from poi.config import DEFAULT_CONFIG_PATH, PipelineConfig

    return tables(PipelineConfig, yaml_key_comments(DEFAULT_CONFIG_PATH.read_text(encoding="utf-8")))


def scenario() -> str:
    from sim.scenario import Scenario

    return tables(Scenario)


def rules() -> str:
    from eval.scoring.rules import Rules

    return tables(Rules)


def cli() -> str:
    import argparse

    from eval.cli.main import build_parser

    parser = build_parser()
    out = []

    def visit(p: argparse.ArgumentParser, name: str) -> None:
        subs = [a for a in p._actions if isinstance(a, argparse._SubParsersAction)]
        if name:
            p.formatter_class = lambda prog: argparse.HelpFormatter(prog, width=100)
            out.append(f"### `{name}`\n\n```text\n{p.format_help().rstrip()}\n```\n")
        for action in subs:
            for sub_name, sub in action.choices.items():
                visit(sub, f"{name} {sub_name}".strip())

    visit(parser, "")
    return "\n".join(out)


def where_it_stands(readme: Path = ROOT / "README.md") -> str:
    r"""The README's "Where it stands" section up to the end of its table: the lead paragraph and the
    table of today's figures, each with the command that reproduces it.

    >>> text = "## Where it stands\n\nMeasured.\n\n| a | b |\n| --- | --- |\n| 1 | 2 |\n\nMore.\n\n## Next\n"
    >>> import tempfile; f = Path(tempfile.mkdtemp()) / "README.md"; _ = f.write_text(text)
    >>> where_it_stands(f)
    'Measured.\n\n| a | b |\n| --- | --- |\n| 1 | 2 |\n'
    """
    text = readme.read_text(encoding="utf-8")
    m = re.search(r"^## Where it stands\n(.*?)(?=^## |\Z)", text, flags=re.S | re.M)
    if m is None:
        raise ValueError(f"{readme}: no '## Where it stands' section")
    lines = m.group(1).strip("\n").splitlines()
    last_row = max((i for i, line in enumerate(lines) if line.startswith("|")), default=None)
    if last_row is None:
        raise ValueError(f"{readme}: the 'Where it stands' section has no table")
    return "\n".join(lines[: last_row + 1]) + "\n"


GENERATORS = {
    "pipeline-config": pipeline_config,
    "scenario": scenario,
    "rules": rules,
    "cli": cli,
    "where-it-stands": where_it_stands,
}


def on_page_markdown(markdown: str, **kwargs: Any) -> str:
    """MkDocs event: put each generated part where its marker is (in place of what a page keeps
    there: the site shows the code's keys as they are at build time)."""
    return MARKER.sub(lambda m: GENERATORS[m.group(1)](), markdown)


def kept_in_page(markdown: str, parts: dict[str, str]) -> str:
    r"""``markdown`` with each kept part (``parts``: name -> generated text) written after its
    marker, up to its end marker.

    >>> kept_in_page("a\n<!-- generated: rules -->\nold\n<!-- end generated -->\nb\n", {"rules": "new\n"})
    'a\n<!-- generated: rules -->\nnew\n<!-- end generated -->\nb\n'
    >>> kept_in_page("<!-- generated: cli -->\n", {"rules": "x"})
    '<!-- generated: cli -->\n'
    """

    def put(m: re.Match) -> str:
        name = m.group(1)
        if name not in parts:
            return m.group(0)
        return f"<!-- generated: {name} -->\n{parts[name].rstrip()}\n{END}"

    return MARKER.sub(put, markdown)


def stale_pages(write: bool = False) -> list[Path]:
    """The pages under docs/ whose kept parts differ from the code's (written afresh with ``write``)."""
    parts = {name: GENERATORS[name]() for name in KEPT_IN_PAGES}
    stale = []
    for page in sorted(DOCS.rglob("*.md")):
        text = page.read_text(encoding="utf-8")
        if not any(f"<!-- generated: {name} -->" in text for name in KEPT_IN_PAGES):
            continue
        fresh = kept_in_page(text, parts)
        if fresh != text:
            stale.append(page)
            if write:
                page.write_text(fresh, encoding="utf-8")
    return stale


if __name__ == "__main__":
    check = sys.argv[1:] == ["--check"]
    if sys.argv[1:] not in ([], ["--check"]):
        sys.exit("usage: python docs/hooks/reference.py [--check]")
    pages = stale_pages(write=not check)
    for page in pages:
        print(f"{page.relative_to(ROOT)}: {'out of date' if check else 'written'}")
    sys.exit(1 if check and pages else 0)
