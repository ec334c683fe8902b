"""The project carries what it cites: every document, section and source key named in the code exists.

Docstrings and comments cite the project's documents by path and section heading
(``docs/FACTS.md "D435 depth"``) and sources by key (``[Avevor2022]_``, listed in
docs/SOURCES.md). These tests collect every such citation from the docstrings, comments
and YAML files of the packages, the tests and bench/, and from the documents themselves,
and check that the file, the heading and the key exist; and that nothing still points at
documents outside the repository or at the source documents by their old nicknames.
"""

from __future__ import annotations

import io
import re
import tokenize
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"
CODE_DIRS = ("sim", "poi", "eval", "maze_assets", "bench", "tests")
THIS_FILE = Path(__file__).resolve()

# docs/NAME.md, optionally followed by a quoted section heading: docs/RULES.md, "The POI file"
DOC_REF = re.compile(r'docs/([A-Za-z_]+\.md)(?:,?\s+(?:section\s+)?"([^"]+)")?')
# A source key in square brackets: a capital letter, then letters, digits or '-', with at least
# one more capital or digit and one lower-case letter or digit (Avevor2022, CFR49-172, OpenCV;
# not a command synopsis's [SCENARIO]).
KEY_REF = re.compile(r"\[([A-Z](?=[A-Za-z0-9-]*[A-Z0-9])(?=[A-Za-z0-9-]*[a-z0-9])[A-Za-z0-9-]{3,})\]")
KEY_DEF = re.compile(r"^- \*\*\[([^\]]+)\]\*\*", re.MULTILINE)
# The documents as they were cited before they were in docs/, and the shared folder.
BARE_DOC = re.compile(r"(?<![\w/])(?:FACTS|RULES|DESIGN|STYLE)\.md")
SHARED_PATH = re.compile(r"\.\./shared|/work/shared|shared/seeds")
# "seed 1" / "seed 2" as names of the source documents (an RNG seed of 1000 does not match).
SEED_NICKNAME = re.compile(r"\bseed [12]\b(?![\d.]\d)", re.IGNORECASE)


def cited_text(path: Path) -> str:
    """The comments and string literals (docstrings included) of a Python file; a YAML
    file's whole text (its comments are where it cites)."""
    source = path.read_text(encoding="utf-8")
    if path.suffix != ".py":
        return source
    parts = [
        tok.string
        for tok in tokenize.generate_tokens(io.StringIO(source).readline)
        if tok.type in (tokenize.COMMENT, tokenize.STRING)
    ]
    return "\n".join(parts)


def code_files() -> list[Path]:
    files = []
    for name in CODE_DIRS:
        for pattern in ("*.py", "*.yaml"):
            files.extend(p for p in (ROOT / name).rglob(pattern) if p.resolve() != THIS_FILE)
    return sorted(files)


def doc_files() -> list[Path]:
    return sorted(DOCS.glob("*.md")) + [ROOT / "README.md"]


def headings(doc: Path) -> set[str]:
    """Every Markdown heading of a document, without its '#' marks."""
    return {
        line.lstrip("#").strip() for line in doc.read_text(encoding="utf-8").splitlines() if line.startswith("#")
    }


def source_keys() -> set[str]:
    return set(KEY_DEF.findall((DOCS / "SOURCES.md").read_text(encoding="utf-8")))


def all_citing_texts() -> list[tuple[Path, str]]:
    return [(p, cited_text(p)) for p in code_files()] + [(p, p.read_text(encoding="utf-8")) for p in doc_files()]


def test_the_documents_exist_and_sources_define_keys():
    for name in ("FACTS.md", "RULES.md", "DESIGN.md", "SOURCES.md"):
        assert (DOCS / name).is_file(), f"docs/{name} is missing"
    keys = source_keys()
    # the two source documents the pipeline is built on
    assert {"Avevor2022", "Bouda2025"} <= keys


def test_every_cited_document_and_section_exists():
    missing = []
    for path, text in all_citing_texts():
        for m in DOC_REF.finditer(text):
            doc = DOCS / m.group(1)
            if not doc.is_file():
                missing.append(f"{path.relative_to(ROOT)}: docs/{m.group(1)} does not exist")
                continue
            if m.group(2) is not None:
                section = " ".join(m.group(2).split())
                if section not in headings(doc):
                    missing.append(f'{path.relative_to(ROOT)}: docs/{m.group(1)} has no section "{section}"')
    assert not missing, "\n".join(missing)


def yaml_comments(text: str) -> str:
    """Only the comments of a YAML file cite: a flow list such as ``[CPUExecutionProvider]`` is a value.

    >>> yaml_comments("providers: [CPUExecutionProvider]  # [IntelTuning]\\nfps: 30")
    ' [IntelTuning]'
    """
    return "\n".join(line.split("#", 1)[1] for line in text.splitlines() if "#" in line)


def test_every_cited_key_is_in_sources():
    keys = source_keys()
    unknown = [
        f"{path.relative_to(ROOT)}: [{m.group(1)}]"
        for path, text in all_citing_texts()
        for m in KEY_REF.finditer(yaml_comments(text) if path.suffix == ".yaml" else text)
        if m.group(1) not in keys
    ]
    assert not unknown, "keys not listed in docs/SOURCES.md:\n" + "\n".join(unknown)


def test_code_cites_sources_by_key():
    """At least the estimation maths cites its sources by key (guards the scan itself: a
    pattern that matched nothing would let every other test pass)."""
    text = cited_text(ROOT / "poi" / "estimation" / "tracker.py")
    assert "[Avevor2022]" in text


def test_each_module_lists_the_keys_it_cites_in_references():
    """A key cited as ``[Key]_`` in a Python file is listed (``.. [Key]``) in that file's
    References section, filterpy's style."""
    cite, define = re.compile(r"\[([A-Za-z][A-Za-z0-9-]+)\]_"), re.compile(r"^\s*\.\. \[([^\]]+)\]", re.MULTILINE)
    unlisted = []
    for path in code_files():
        if path.suffix != ".py":
            continue
        text = cited_text(path)
        missing = set(cite.findall(text)) - set(define.findall(text))
        unlisted += [f"{path.relative_to(ROOT)}: [{key}]_" for key in sorted(missing)]
    assert not unlisted, "cited without a References entry:\n" + "\n".join(unlisted)


@pytest.mark.parametrize("pattern", [BARE_DOC, SHARED_PATH, SEED_NICKNAME], ids=["bare-doc", "shared", "seed-n"])
def test_no_citation_points_outside_the_repository(pattern):
    found = [
        f"{path.relative_to(ROOT)}: {m.group(0)!r}"
        for path in code_files() + [ROOT / "README.md"]
        for m in pattern.finditer(cited_text(path))
    ]
    assert not found, "\n".join(found)


def test_patterns_match_what_they_are_meant_to():
    assert DOC_REF.search('see docs/FACTS.md "D435\n   depth"').groups() == ("FACTS.md", "D435\n   depth")
    assert KEY_REF.findall("([Avevor2022]_, 2.4.3) [CFR49-172] C[A, B] [0, 1) [Frame] [SCENARIO]") == [
        "Avevor2022",
        "CFR49-172",
    ]
    assert BARE_DOC.findall("FACTS.md and docs/FACTS.md") == ["FACTS.md"]
    assert SEED_NICKNAME.findall("seed 1 2.4.4, seed 2, --seed 1000") == ["seed 1", "seed 2"]


def test_the_alias_tables_of_the_rules_page_are_the_codes():
    """docs/RULES.md's two alias tables ("Type names", "Hazmat labels") list every alias
    poi.core.names maps, each to what the code maps it to, and none it does not."""
    from poi.core.names import LABEL_ALIASES, TYPE_ALIASES

    page = (DOCS / "RULES.md").read_text(encoding="utf-8")
    written: dict[str, str] = {}
    for line in page.splitlines():
        m = re.fullmatch(r"\| ((?:`[a-z-]+`(?:, )?)+) \| ((?:`[a-z-]+`(?:, )?)+) \|", line.strip())
        if m is None:
            continue
        aliases, targets = (re.findall(r"`([a-z-]+)`", g) for g in m.groups())
        # one target for all, or one target an alias (the pillars' row)
        for alias, target in zip(aliases, targets * len(aliases) if len(targets) == 1 else targets, strict=True):
            written[alias] = target
    assert written == {**TYPE_ALIASES, **LABEL_ALIASES}
