"""The README and the documentation site say what the code is.

- every path in docs/DESIGN.md's layout tree exists, and every package is in it;
- every ``poibench ...`` command in README.md (its fenced shell blocks and the command
  column of its tables) parses with the CLI's own argparse parser;
- the README stays a README (at most 400 lines);
- ``mkdocs build --strict`` builds the site (skipped only where mkdocs is not installed;
  .ci/run installs the ``docs`` extra, so CI builds it);
- the generated configuration reference holds every key of the pipeline and the scenario.
"""

from __future__ import annotations

import contextlib
import html
import importlib.util
import io
import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
README = ROOT / "README.md"
DESIGN = ROOT / "docs/DESIGN.md"
PACKAGES = ("sim", "poi", "eval", "maze_assets")
# In the tree, a line whose text starts at this column or later continues the description above.
DESCRIPTION_COLUMN = 24


# ---------------------------------------------------------------------------------------------
# docs/DESIGN.md's layout tree


def layout_tree(text: str) -> list[str]:
    """The lines of the code block under docs/DESIGN.md's "## Layout" heading."""
    section = text.split("\n## Layout\n", 1)[1].split("\n## ", 1)[0]
    m = re.search(r"```text\n(.*?)```", section, re.S)
    if m is None:
        raise ValueError('docs/DESIGN.md "Layout" has no ```text block')
    return m.group(1).splitlines()


def tree_paths(lines: list[str]) -> list[str]:
    """The paths a layout tree names, each relative to the repository root.

    Two spaces of indent a level; names (several split by ", ") up to the first run of two
    spaces; a folder ends with "/"; a line starting at DESCRIPTION_COLUMN or later continues
    the description above it.

    >>> tree_paths(["sim/                    the world", "  a.py, b.py            two",
    ...             "                        more of it", "  sensors/              one a file",
    ...             "    t265.py             the T265", "poi/                    the pipeline"])
    ['sim/', 'sim/a.py', 'sim/b.py', 'sim/sensors/', 'sim/sensors/t265.py', 'poi/']
    """
    paths: list[str] = []
    stack: list[str] = []
    for line in lines:
        if not line.strip():
            continue
        indent = len(line) - len(line.lstrip(" "))
        if indent >= DESCRIPTION_COLUMN:
            continue
        if indent % 2:
            raise ValueError(f"odd indent in the layout tree: {line!r}")
        names = re.split(r" {2,}", line.strip())[0]
        stack = stack[: indent // 2]
        for name in names.split(", "):
            paths.append("/".join([*stack, name]))
        if names.endswith("/") and ", " not in names:
            stack.append(names.rstrip("/"))
    return paths


def test_every_path_in_the_design_tree_exists():
    paths = tree_paths(layout_tree(DESIGN.read_text(encoding="utf-8")))
    assert len(paths) > 100, "the tree parsed into too few paths: is its format still two spaces a level?"
    missing = [p for p in paths if not (ROOT / p).exists()]
    assert not missing, "docs/DESIGN.md's layout names paths that do not exist:\n" + "\n".join(missing)


def test_every_package_is_in_the_design_tree():
    listed = {p.rstrip("/") for p in tree_paths(layout_tree(DESIGN.read_text(encoding="utf-8")))}
    packages = sorted(
        str(init.parent.relative_to(ROOT)) for name in PACKAGES for init in (ROOT / name).rglob("__init__.py")
    )
    unlisted = [p for p in packages if p not in listed]
    assert not unlisted, "packages missing from docs/DESIGN.md's layout tree:\n" + "\n".join(unlisted)


def test_every_module_is_in_the_design_tree():
    """Each tracked module of the four packages is a path of the tree, or, where the tree names a
    folder's modules in a line of prose (shapes/, cli/), named there."""
    tree = layout_tree(DESIGN.read_text(encoding="utf-8"))
    listed, text = set(tree_paths(tree)), "\n".join(tree)
    tracked = subprocess.run(["git", "ls-files", *PACKAGES], cwd=ROOT, capture_output=True, text=True, check=True)
    modules = [f for f in tracked.stdout.split() if f.endswith(".py") and not f.endswith("__init__.py")]
    unlisted = [f for f in modules if f not in listed and not re.search(rf"\b{Path(f).stem}\b", text)]
    assert len(modules) > 100 and not unlisted, "modules missing from docs/DESIGN.md's layout tree:\n" + "\n".join(
        unlisted
    )


def test_the_tree_test_fails_on_a_missing_path():
    lines = ["sim/                    the world", "  no_such_module.py     gone"]
    assert not (ROOT / tree_paths(lines)[1]).exists()


# ---------------------------------------------------------------------------------------------
# README.md's commands


def fenced_shell_blocks(text: str) -> list[str]:
    return re.findall(r"```(?:bash|sh|shell|console)\n(.*?)```", text, re.S)


def table_command_cells(text: str) -> list[str]:
    """The code spans of the column headed "command" in every Markdown table."""
    cells: list[str] = []
    column = None
    for line in text.splitlines():
        if not line.startswith("|"):
            column = None
            continue
        row = [c.strip() for c in re.split(r"(?<!\\)\|", line.strip())[1:-1]]
        if column is None:
            column = row.index("command") if "command" in row else -1
            continue
        if column >= 0 and column < len(row) and not set(row[column]) <= set("-: "):
            cells += re.findall(r"`([^`]+)`", row[column])
    return cells


def poibench_commands(shell: str) -> list[list[str]]:
    """The argument lists of the ``poibench`` commands in shell text: continuation lines
    joined, comments dropped, split at ``&&``, ``;`` and ``|``; a command may be run by a
    path (``~/venv/bin/poibench``) or after ``VAR=value``.

    >>> poibench_commands("pip install -e . && poibench run --out t  # a trial\\n"
    ...                   "for s in 1 2; do poibench run --seed $s \\\\\\n  --quiet; done")
    [['run', '--out', 't'], ['run', '--seed', '$s', '--quiet']]
    """
    commands: list[list[str]] = []
    for line in shell.replace("\\\n", " ").splitlines():
        commands += _line_commands(line)
    return commands


def _line_commands(line: str) -> list[list[str]]:
    lexer = shlex.shlex(line, posix=True, punctuation_chars=";&|")
    lexer.whitespace_split = True
    lexer.commenters = "#"
    commands: list[list[str]] = []
    segment: list[str] = []
    for token in [*lexer, ";"]:
        if token and set(token) <= set(";&|"):
            heads = [i for i, t in enumerate(segment) if t == "poibench" or t.endswith("/poibench")]
            if heads:
                commands.append(segment[heads[0] + 1 :])
            segment = []
        else:
            segment.append(token)
    return commands


def readme_commands() -> list[list[str]]:
    text = README.read_text(encoding="utf-8")
    commands = [c for block in fenced_shell_blocks(text) for c in poibench_commands(block)]
    for cell in table_command_cells(text):
        commands += poibench_commands(cell)
    return commands


README_COMMANDS = readme_commands()


def test_the_readme_has_commands_to_check():
    assert len(README_COMMANDS) >= 20
    cells = table_command_cells(README.read_text(encoding="utf-8"))  # "Where it stands" has a command column
    assert any(c.startswith("poibench suite run ") for c in cells)


@pytest.fixture(scope="module")
def parser():
    from eval.cli.main import build_parser

    return build_parser()


def parse_error(parser, argv: list[str]) -> str | None:
    """argparse's message when ``argv`` does not parse, else None."""
    err = io.StringIO()
    try:
        with contextlib.redirect_stderr(err):
            parser.parse_args(argv)
    except SystemExit as e:
        if e.code not in (0, None):
            return err.getvalue().strip().splitlines()[-1]
    return None


@pytest.mark.parametrize("argv", README_COMMANDS, ids=[" ".join(c)[:60] for c in README_COMMANDS])
def test_each_readme_command_parses(parser, argv):
    error = parse_error(parser, argv)
    assert error is None, f"README.md: `poibench {shlex.join(argv)}` does not parse: {error}"


def test_a_command_that_does_not_parse_is_caught(parser):
    assert parse_error(parser, ["run", "--no-such-flag"]) is not None
    assert parse_error(parser, ["suite", "run"]) is not None  # the suite's name is missing
    assert parse_error(parser, ["run", "--out", "t"]) is None


def test_the_readme_is_at_most_400_lines():
    n = len(README.read_text(encoding="utf-8").splitlines())
    assert n <= 400, f"README.md has {n} lines; move detail to the site (docs/)"


# ---------------------------------------------------------------------------------------------
# The site


def load_hook():
    spec = importlib.util.spec_from_file_location("docs_reference_hook", ROOT / "docs" / "hooks" / "reference.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclasses look their module up
    spec.loader.exec_module(module)
    return module


def test_the_configuration_reference_has_every_key_with_a_meaning():
    import dataclasses

    from poi.config import PipelineConfig

    hook = load_hook()
    pipeline = hook.pipeline_config()
    for f in dataclasses.fields(PipelineConfig):
        assert f"`{f.name}" in pipeline
    assert "| `tracker.gate` | a number | `9.0` | > 0 | Mahalanobis gate" in pipeline
    # every pipeline key carries its meaning (poi/configs/default.yaml documents each)
    empty = [line.split("|")[1].strip() for line in pipeline.splitlines() if line.rstrip().endswith("|  |")]
    assert not empty, f"pipeline keys without a meaning: {empty}"
    scenario = hook.scenario()
    for key in ("sensors.d435.depth.window_px", "sensors.t265.drift_fraction", "maze.generate.rows", "lighting"):
        assert f"| `{key}` |" in scenario, key
    assert "| `maze.generate.rows` | an integer | `4` | >= 1 and <= 64 |" in scenario


def test_every_command_has_a_row_in_the_commands_page(parser):
    """docs/reference/commands.md's table names every command the parser has, subcommands of `suite` too."""
    import argparse

    rows = [
        line
        for line in (ROOT / "docs" / "reference" / "commands.md").read_text().splitlines()
        if line.startswith("| `poibench ")
    ]

    def commands(p: argparse.ArgumentParser, name: str):
        subs = [a for a in p._actions if isinstance(a, argparse._SubParsersAction)]
        if name and not subs:
            yield name
        for action in subs:
            for sub_name, sub in action.choices.items():
                yield from commands(sub, f"{name} {sub_name}".strip())

    named = {c for c in commands(parser, "") for r in rows if re.match(rf"\| `poibench {c}[ `]", r)}
    assert named == set(commands(parser, "")), set(commands(parser, "")) - named


def test_the_key_tables_kept_in_the_pages_are_up_to_date():
    """docs/reference/configuration.md keeps the keys' tables for readers of the Markdown; a key added,
    renamed or given another range or meaning makes them stale until the hook writes them again."""
    hook = load_hook()
    stale = hook.stale_pages()
    assert not stale, f"out of date: {stale}; run python docs/hooks/reference.py"
    page = (ROOT / "docs" / "reference" / "configuration.md").read_text(encoding="utf-8")
    assert "| `tracker.gate` | a number | `9.0` | > 0 |" in page
    # a page whose table has a wrong row is written back to the code's table
    assert (
        hook.kept_in_page(
            page.replace("| `tracker.gate` |", "| `tracker.gatex` |"), {"pipeline-config": hook.pipeline_config()}
        )
        == page
    )


def test_the_hook_examples_run():
    import doctest

    assert doctest.testmod(load_hook()).failed == 0


@pytest.mark.skipif(
    importlib.util.find_spec("mkdocs") is None and not os.environ.get("CI"),
    reason="mkdocs not installed (extra 'docs'); CI installs it and never skips this",
)
def test_mkdocs_build_strict(tmp_path):
    result = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(tmp_path / "site")],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=600,
        env={**os.environ, "NO_MKDOCS_2_WARNING": "1"},
    )
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-3000:]
    page = (tmp_path / "site" / "reference" / "configuration" / "index.html").read_text(encoding="utf-8")
    assert "tracker.gate" in page and "<!-- generated" not in page
    # the results page shows the README's "Where it stands" table, row for row
    results = (tmp_path / "site" / "results" / "index.html").read_text(encoding="utf-8")
    rows = [line for line in load_hook().where_it_stands().splitlines() if line.startswith("| ")][2:]
    assert len(rows) >= 5 and "<!-- generated" not in results
    for row in rows:
        figure = row.split(" | ")[1][:12]  # the "now" cell's opening words, e.g. "60 / 60, no "
        assert html.escape(figure, quote=False) in results, figure
