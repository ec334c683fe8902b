"""Seeded mutations of the shipped input files, and the loaders they are fed to.

Shared by ``bench/bench_fuzz_loaders.py`` (10,000 mutated files a loader) and
``tests/poi/core/test_loader_fuzz.py`` (hypothesis, a few dozen a loader), so both
exercise the same mutations against the same public entry points. Not a library
module: the test imports it by path.

A mutation is ``(kind, seed)``: :func:`apply_op` runs mutation ``kind`` with a
``numpy`` Generator made from ``seed``, so every mutated file is reproducible from
the shipped file it started from and a list of such pairs.

The property under test (issue 16): every input either loads or raises the
project's own error, a ``ValueError`` subclass defined in ``sim``, ``poi``, ``eval``
or ``maze_assets``: the errors the CLI turns into ``poibench CMD: error: ...`` and
exit status 2 (``eval/cli/main.py`` ``_is_user_error``). Anything else (a built-in
``ValueError``, ``KeyError``, ``RecursionError``, ``yaml.YAMLError``, ...) escaping
is a *foreign* exception: a bug.
"""

from __future__ import annotations

import re
import signal
import zlib
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from functools import cache
from pathlib import Path

import numpy as np

PROJECT_PACKAGES = ("sim", "poi", "eval", "maze_assets")
REPO = Path(__file__).resolve().parents[1]

# ---------------------------------------------------------------------------- nasty values

DEEP_LIST = b"[" * 1000 + b"]" * 1000
DEEP_MAP = b"{a: " * 1000 + b"1" + b"}" * 1000
ALIAS_BOMB_FLOW = (
    b'[&a ["lol","lol","lol","lol","lol","lol","lol","lol","lol"], '
    + b", ".join(b"&%c [%s]" % (c, b",".join([b"*" + bytes([c - 1])] * 9)) for c in b"bcdefghi")
    + b"]"
)
# The classic 350-byte "billion laughs": nine anchors, each nine aliases of the one before,
# so a reader that expands aliases builds 9**9 = 387,420,489 strings.
ALIAS_BOMB_FILE = b'a: &a ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]\n' + b"".join(
    b"%c: &%c [%s]\n" % (c, c, b",".join([b"*" + bytes([c - 1])] * 9)) for c in b"bcdefghi"
)

NASTY: tuple[bytes, ...] = (
    b"1e400",
    b"-1e400",
    b"1" + b"0" * 400,  # 10**400: beyond float range
    b"9" * 5000,  # beyond Python's int-from-string digit limit (4300)
    b"-1",
    b"0",
    b"-0",
    b"1e-400",
    b"1e300",  # finite, but a distance between two such points overflows to inf
    b"-1.7976931348623157e308",
    b"-9223372036854775809",
    b".inf",
    b"-.inf",
    b".nan",
    b"''",
    b'""',
    b"~",
    b"null",
    b"true",
    b"no",
    b"0x7fffffffffffffff",
    b"0o777",
    b"1_000",
    b"2026-11-22",
    b"2026-11-22T01:02:03Z",
    b"x" * 100_000,
    b"\xff\xfe\x80",
    b"\x00",
    b"\xef\xbb\xbf",
    b"\\",
    b"'\\",
    b'"\\ud800"',
    b'"\\x00\\u202e"',
    b"[]",
    b"{}",
    b"[1, 2]",
    b"{a: 1}",
    b"*undefined",
    b"&anchor",
    b"!!binary aGVsbG8=",
    b"!!python/object/apply:os.system ['true']",
    b"!!set {a, b}",
    b"!!omap [a: 1]",
    b"!!float 1",
    b"<<: {}",
    b"? [a]",
    b"|",
    b"%YAML 1.1",
    b"---",
    b"=",
    b",",
    DEEP_LIST,
    DEEP_MAP,
    ALIAS_BOMB_FLOW,
)
TYPE_SWAPS: tuple[bytes, ...] = (b"[1, 2]", b"{a: 1}", b"text", b"3", b"3.5", b"true", b"null", b"[]", b"{}")

# A value after "key: ", "- ", "[", ", " or "="; else any run of non-blank bytes.
_VALUE_RE = re.compile(rb"(?:(?<=: )|(?<=- )|(?<=\[)|(?<=, )|(?<==)|(?<=,))[^\s,\[\]{}#]+")
_TOKEN_RE = re.compile(rb"[^\s,]+")
_KEY_LINE_RE = re.compile(rb"^([ \t]*)([^\s:#][^:\n]*):")


# ---------------------------------------------------------------------------- mutations


def _lines(data: bytes) -> list[bytes]:
    return data.splitlines(keepends=True) or [b""]


def _pick(rng: np.random.Generator, seq: Sequence):
    return seq[int(rng.integers(len(seq)))]


def byte_flip(data: bytes, rng: np.random.Generator, donors: Sequence[bytes]) -> tuple[bytes, str]:
    """Flip one to four random bits."""
    if not data:
        return b"\xff", "byte_flip(empty)"
    b = bytearray(data)
    where = []
    for _ in range(int(rng.integers(1, 5))):
        i = int(rng.integers(len(b)))
        b[i] ^= 1 << int(rng.integers(8))
        where.append(i)
    return bytes(b), f"byte_flip@{where}"


def byte_insert(data: bytes, rng: np.random.Generator, donors: Sequence[bytes]) -> tuple[bytes, str]:
    """Insert 1-8 random bytes (any value, so also non-UTF-8 and NUL)."""
    i = int(rng.integers(len(data) + 1))
    ins = rng.integers(0, 256, int(rng.integers(1, 9)), dtype=np.uint8).tobytes()
    return data[:i] + ins + data[i:], f"byte_insert@{i}:{ins!r}"


def byte_delete(data: bytes, rng: np.random.Generator, donors: Sequence[bytes]) -> tuple[bytes, str]:
    """Delete a span of 1-16 bytes."""
    if not data:
        return data, "byte_delete(empty)"
    i = int(rng.integers(len(data)))
    n = int(rng.integers(1, 17))
    return data[:i] + data[i + n :], f"byte_delete@{i}+{n}"


def truncate(data: bytes, rng: np.random.Generator, donors: Sequence[bytes]) -> tuple[bytes, str]:
    """Cut the file at a random byte."""
    i = int(rng.integers(len(data) + 1))
    return data[:i], f"truncate@{i}"


def line_dup(data: bytes, rng: np.random.Generator, donors: Sequence[bytes]) -> tuple[bytes, str]:
    """Duplicate a line (for YAML mostly a duplicate key)."""
    lines = _lines(data)
    i = int(rng.integers(len(lines)))
    j = int(rng.integers(len(lines) + 1))
    line = lines[i] if lines[i].endswith(b"\n") else lines[i] + b"\n"
    return b"".join(lines[:j] + [line] + lines[j:]), f"line_dup({i + 1}->{j + 1})"


def line_delete(data: bytes, rng: np.random.Generator, donors: Sequence[bytes]) -> tuple[bytes, str]:
    """Delete one line."""
    lines = _lines(data)
    i = int(rng.integers(len(lines)))
    return b"".join(lines[:i] + lines[i + 1 :]), f"line_delete({i + 1})"


def line_swap(data: bytes, rng: np.random.Generator, donors: Sequence[bytes]) -> tuple[bytes, str]:
    """Swap two lines."""
    lines = _lines(data)
    i, j = (int(k) for k in rng.integers(len(lines), size=2))
    lines[i], lines[j] = lines[j], lines[i]
    return b"".join(lines), f"line_swap({i + 1},{j + 1})"


def splice(data: bytes, rng: np.random.Generator, donors: Sequence[bytes]) -> tuple[bytes, str]:
    """Insert or overwrite with 1-4 consecutive lines of another shipped file."""
    lines = _lines(data)
    donor = _lines(_pick(rng, donors)) if donors else lines
    k = int(rng.integers(len(donor)))
    chunk = donor[k : k + int(rng.integers(1, 5))]
    chunk = [c if c.endswith(b"\n") else c + b"\n" for c in chunk]
    i = int(rng.integers(len(lines) + 1))
    drop = int(rng.integers(0, 2)) * len(chunk)  # half the time overwrite, else insert
    return b"".join(lines[:i] + chunk + lines[i + drop :]), f"splice({len(chunk)} lines @{i + 1}, drop {drop})"


def _replace_value(data: bytes, rng: np.random.Generator, values: Sequence[bytes], tag: str) -> tuple[bytes, str]:
    spans = [m.span() for m in _VALUE_RE.finditer(data)] or [m.span() for m in _TOKEN_RE.finditer(data)]
    value = _pick(rng, values)
    shown = value if len(value) <= 40 else value[:20] + b"...(%d bytes)" % len(value)
    if not spans:
        return data + value, f"{tag}(append {shown!r})"
    a, b = _pick(rng, spans)
    line = data.count(b"\n", 0, a) + 1
    return data[:a] + value + data[b:], f"{tag}(line {line}: {data[a:b][:30]!r} -> {shown!r})"


def nasty_scalar(data: bytes, rng: np.random.Generator, donors: Sequence[bytes]) -> tuple[bytes, str]:
    """Replace a value with a nasty one: huge/non-finite numbers, non-UTF-8, deep nesting, alias bomb, ..."""
    return _replace_value(data, rng, NASTY, "nasty_scalar")


def type_swap(data: bytes, rng: np.random.Generator, donors: Sequence[bytes]) -> tuple[bytes, str]:
    """Replace a value with one of another type (list, mapping, string, number, bool, null)."""
    return _replace_value(data, rng, TYPE_SWAPS, "type_swap")


TAGS: tuple[bytes, ...] = (
    b"int", b"float", b"bool", b"null", b"str", b"timestamp", b"binary", b"map", b"seq", b"set"
)  # fmt: skip
TAGGED: tuple[bytes, ...] = (b"", b"''", b"+", b"-", b"x", b".", b"1:2", b"0x", b"[]", b"{}", b"1")


def explicit_tag(data: bytes, rng: np.random.Generator, donors: Sequence[bytes]) -> tuple[bytes, str]:
    """Replace a value with an explicitly tagged odd scalar (``!!int ''``, ``!!timestamp x``, ``!!float``)."""
    value = b"!!" + _pick(rng, TAGS) + (b" " + _pick(rng, TAGGED)).rstrip()
    return _replace_value(data, rng, (value,), "explicit_tag")


def _key_lines(lines: list[bytes]) -> list[int]:
    return [i for i, line in enumerate(lines) if _KEY_LINE_RE.match(line)]


def unknown_key(data: bytes, rng: np.random.Generator, donors: Sequence[bytes]) -> tuple[bytes, str]:
    """Insert ``zz_unknown: 1`` beside a random ``key:`` line, at its indentation."""
    lines = _lines(data)
    keyed = _key_lines(lines) or [0]
    i = _pick(rng, keyed)
    m = _KEY_LINE_RE.match(lines[i])
    indent = m.group(1) if m else b""
    return b"".join(lines[: i + 1] + [indent + b"zz_unknown: 1\n"] + lines[i + 1 :]), f"unknown_key(after {i + 1})"


def duplicate_key(data: bytes, rng: np.random.Generator, donors: Sequence[bytes]) -> tuple[bytes, str]:
    """Repeat a ``key:`` line right after itself with a different value."""
    lines = _lines(data)
    keyed = _key_lines(lines)
    if not keyed:
        return line_dup(data, rng, donors)
    i = _pick(rng, keyed)
    m = _KEY_LINE_RE.match(lines[i])
    dup = m.group(0) + b" " + _pick(rng, TYPE_SWAPS) + b"\n"
    return b"".join(lines[: i + 1] + [dup] + lines[i + 1 :]), f"duplicate_key(line {i + 1})"


def encoding(data: bytes, rng: np.random.Generator, donors: Sequence[bytes]) -> tuple[bytes, str]:
    """Re-encode: UTF-16, Latin-1 bytes, CRLF line ends, a BOM, a NUL, a lone CR."""
    choice = int(rng.integers(6))
    if choice == 0:
        return data.decode("utf-8", "replace").encode("utf-16"), "encoding(utf-16)"
    if choice == 1:
        return data.replace(b"e", b"\xe9"), "encoding(latin-1 e-acute)"
    if choice == 2:
        return data.replace(b"\n", b"\r\n"), "encoding(crlf)"
    if choice == 3:
        return b"\xef\xbb\xbf" + data, "encoding(bom)"
    if choice == 4:
        return data.replace(b"\n", b"\r"), "encoding(lone cr)"
    i = int(rng.integers(len(data) + 1))
    return data[:i] + b"\x00" + data[i:], f"encoding(nul@{i})"


MUTATIONS: dict[str, Callable[[bytes, np.random.Generator, Sequence[bytes]], tuple[bytes, str]]] = {
    f.__name__: f
    for f in (
        byte_flip,
        byte_insert,
        byte_delete,
        truncate,
        line_dup,
        line_delete,
        line_swap,
        splice,
        nasty_scalar,
        type_swap,
        explicit_tag,
        unknown_key,
        duplicate_key,
        encoding,
    )
}
KINDS: tuple[str, ...] = tuple(MUTATIONS)


def apply_op(data: bytes, kind: str, seed: int, donors: Sequence[bytes]) -> tuple[bytes, str]:
    """Mutation ``kind`` with a Generator seeded by ``seed``: (new bytes, what was done)."""
    return MUTATIONS[kind](data, np.random.default_rng(seed), donors)


def case_ops(seed: int, loader: str, case: int) -> list[tuple[str, int]]:
    """The 1-3 (kind, seed) mutations of bench case ``case`` for ``loader``, from ``seed``."""
    rng = np.random.default_rng([seed, zlib.crc32(loader.encode()), case])
    n = int(rng.integers(1, 4))
    return [(KINDS[int(rng.integers(len(KINDS)))], int(rng.integers(2**32))) for _ in range(n)]


def mutate(data: bytes, ops: Sequence[tuple[str, int]], donors: Sequence[bytes]) -> tuple[bytes, list[str]]:
    """Apply ``ops`` in turn; return the bytes and one description per op."""
    done = []
    for kind, seed in ops:
        data, what = apply_op(data, kind, seed, donors)
        done.append(what)
    return data, done


# ---------------------------------------------------------------------------- loaders


@dataclass(frozen=True)
class Loader:
    """A public loader entry point fed one file: its shipped seed files and how to call it."""

    name: str
    suffix: str
    seeds: Callable[[], list[bytes]]
    call: Callable[[Path], object]
    yaml: bool = True  # takes YAML (so the alias bomb is timed through it)


def _files(folder: Path, pattern: str) -> list[bytes]:
    return [p.read_bytes() for p in sorted(folder.glob(pattern))]


def _scenario_seeds() -> list[bytes]:
    from maze_assets import SCENARIOS_DIR

    return _files(SCENARIOS_DIR, "*.yaml")


def _load_scenario(path: Path) -> object:
    from sim.scenario import load_scenario

    return load_scenario(path)


@cache
def _base_scenario():
    from sim.scenario import load_scenario

    return load_scenario("default")


def _settings_lines(data: dict) -> bytes:
    """``key=value`` lines (value as one-line YAML) for every leaf of a nested settings dict."""
    import yaml

    from poi.config import flatten_config

    out = []
    for key, value in flatten_config(data):
        text = yaml.safe_dump(value, default_flow_style=True, width=10**6).removesuffix("\n...\n").strip()
        out.append(f"{key}={text}\n")
    return "".join(out).encode()


def _scenario_settings_seeds() -> list[bytes]:
    return [_settings_lines(_base_scenario().to_dict())]


def _settings_items(path: Path) -> list[str]:
    """The lines of a settings file as ``--set`` items (undecodable bytes kept as surrogates, as argv has them)."""
    return path.read_bytes().decode("utf-8", "surrogateescape").splitlines()


def _apply_scenario_settings(path: Path) -> object:
    from sim.scenario import apply_settings

    return apply_settings(_base_scenario(), _settings_items(path))


def _maze_seeds() -> list[bytes]:
    from maze_assets import MAZES_DIR

    return _files(MAZES_DIR, "*.maze")


def _load_maze(path: Path) -> object:
    from sim.world.maze import load_maze

    return load_maze(path)


def _config_seeds() -> list[bytes]:
    from poi.config import DEFAULT_CONFIG_PATH

    return _files(DEFAULT_CONFIG_PATH.parent, "*.yaml")


def _load_config(path: Path) -> object:
    from poi.config import load_config

    return load_config(path)


@cache
def _base_config():
    from poi.config import load_config

    return load_config()


def _config_settings_seeds() -> list[bytes]:
    from poi.config import config_to_dict

    return [_settings_lines(config_to_dict(_base_config()))]


def _apply_config_settings(path: Path) -> object:
    from poi.config import apply_overrides

    return apply_overrides(_base_config(), _settings_items(path))


def _rules_seeds() -> list[bytes]:
    from eval.scoring.rules import RULES_DIR

    return _files(RULES_DIR, "*.yaml")


def _load_rules(path: Path) -> object:
    from eval.scoring.rules import load_rules

    return load_rules(path)


def _suite_seeds() -> list[bytes]:
    from eval.experiments.suites import SUITES_DIR

    return _files(SUITES_DIR, "*.yaml")


def _load_suite(path: Path) -> object:
    from eval.experiments.suites import load_suite

    return load_suite(path)


def _calibration_seeds() -> list[bytes]:
    import poi

    return [(Path(poi.__file__).parent / "models" / "default_calibration.yaml").read_bytes()]


def _load_calibration(path: Path) -> object:
    from poi.estimation.covariance import load_calibration

    return load_calibration(path)


# A small report and its ground truth, written by the project's own writer: every kind of
# row the scorer treats differently (hazmat label, QR text, plain objects, an unmatched report).
_POI_ROWS = (
    # id, text, x, y, z, type
    (0, "dangerous-when-wet", 2.021, -0.575, 0.332, "hazmat"),
    (1, "Chart B", 4.174, -0.257, 0.839, "qr"),
    (2, "", 3.026, -3.523, 0.532, "door"),
    (3, "organic-peroxide", -0.572, 0.251, 0.753, "hazmat"),
    (4, "", 0.465, -2.359, 0.310, "fire-extinguisher"),
    (5, "", 2.862, -1.283, 0.059, "baby-doll"),
    (6, "Chart A", 2.220, -1.794, 0.330, "qr"),
    (7, "", 4.052, -2.289, 0.201, "heat-source"),
)


def _poi_text(truth: bool) -> bytes:
    from poi.core.poi_file import PoiHeader, PoiRow, format_poi_text

    header = PoiHeader(team="fuzz", country="Simland", date="2026-07-01", start_time="09:00:00", mission="m")
    rows = [
        PoiRow(
            line=0,
            id=i,
            time="09:00:00" if truth else f"09:00:{i:02d}",
            text=text,
            x=x + (0.0 if truth else 0.05 * (i % 3)),
            y=y,
            z=z,
            robot="sim" if truth else "fuzz",
            mode="GT" if truth else "A",
            type=type_,
        )
        for i, text, x, y, z, type_ in _POI_ROWS[: None if truth else -1]
    ]
    return format_poi_text(header, rows).encode()


def _poi_seeds() -> list[bytes]:
    return [_poi_text(truth=False), _poi_text(truth=True)]


@cache
def _poi_context():
    from eval.scoring.rules import PRESETS, load_rules
    from poi.core.poi_file import parse_poi_text

    rules = [load_rules(name) for name in PRESETS]
    return parse_poi_text(_poi_text(False).decode()), parse_poi_text(_poi_text(True).decode()), rules


def _read_and_score(path: Path) -> object:
    """Read the file, then score it as the report against the truth and as the truth against the
    report, under every shipped rules preset (points and map-error scoring)."""
    from eval.scoring.scorer import score
    from poi.core.poi_file import read_poi_file

    pf = read_poi_file(path)
    reports, truth, presets = _poi_context()
    return [(score(pf, truth, r), score(reports, pf, r)) for r in presets]


LOADERS: dict[str, Loader] = {
    loader.name: loader
    for loader in (
        Loader("scenario", ".yaml", _scenario_seeds, _load_scenario),
        Loader("scenario-set", ".txt", _scenario_settings_seeds, _apply_scenario_settings),
        Loader("maze", ".maze", _maze_seeds, _load_maze, yaml=False),
        Loader("config", ".yaml", _config_seeds, _load_config),
        Loader("config-set", ".txt", _config_settings_seeds, _apply_config_settings),
        Loader("rules", ".yaml", _rules_seeds, _load_rules),
        Loader("suite", ".yaml", _suite_seeds, _load_suite),
        Loader("calibration", ".yaml", _calibration_seeds, _load_calibration),
        Loader("poi", ".csv", _poi_seeds, _read_and_score, yaml=False),
    )
}


@cache
def seed_files(name: str) -> tuple[bytes, ...]:
    """The shipped (or, for POI files and settings, generated) files loader ``name`` starts from."""
    return tuple(LOADERS[name].seeds())


@cache
def all_donors() -> tuple[bytes, ...]:
    """Every seed file of every loader: lines to splice between them."""
    return tuple(d for name in LOADERS for d in seed_files(name))


def alias_bomb(name: str) -> bytes:
    """The 350-byte alias bomb as loader ``name`` gets it: a whole file, or a ``--set`` value."""
    if name.endswith("-set"):
        key = seed_files(name)[0].split(b"=", 1)[0]
        return key + b"=" + ALIAS_BOMB_FLOW + b"\n"
    return ALIAS_BOMB_FILE


def big_file(name: str, size: int) -> bytes:
    """A file of about ``size`` bytes that loader ``name`` must read whole before it can refuse it: the
    first seed file with a long flow list under an unknown key (YAML), a long list value (``--set``),
    repeated drawing rows (.maze) or repeated report rows (POI file)."""
    seed = seed_files(name)[0]
    if name.endswith("-set"):
        key = seed.split(b"=", 1)[0]
        return key + b"=[" + b"1, " * max(0, (size - len(key)) // 3 - 1) + b"1]\n"
    if LOADERS[name].yaml:
        return seed + b"zz_big: [" + b"1, " * max(0, (size - len(seed)) // 3 - 4) + b"1]\n"
    lines = _lines(seed)
    if name == "maze":
        i = next(k for k, line in enumerate(lines) if line.startswith(b"|"))
        pair = lines[i] + lines[i + 1]  # a cell row and the wall line below it
        return b"".join(lines[:i]) + pair * max(0, (size - len(seed)) // len(pair)) + b"".join(lines[i:])
    return seed + lines[-1] * max(0, (size - len(seed)) // len(lines[-1]))


# ---------------------------------------------------------------------------- outcome


def is_own_error(exc: BaseException) -> bool:
    """A ValueError subclass defined in the project: what the CLI reports as ``error: ...``."""
    mod = type(exc).__module__ or ""
    return isinstance(exc, ValueError) and mod.partition(".")[0] in PROJECT_PACKAGES


def project_frame(exc: BaseException) -> str:
    """``path:line`` of the innermost traceback frame in the project's packages (where it escaped from)."""
    import traceback

    where = ""
    for fs in traceback.extract_tb(exc.__traceback__):
        path = Path(fs.filename).resolve()
        if path.is_relative_to(REPO) and path.relative_to(REPO).parts[0] in PROJECT_PACKAGES:
            where = f"{path.relative_to(REPO)}:{fs.lineno}"
    return where


class CaseTimeout(BaseException):
    """Raised by :func:`watchdog` in the case that ran too long (a BaseException, so no loader swallows it)."""


@contextmanager
def watchdog(seconds: float) -> Iterator[None]:
    """Raise :class:`CaseTimeout` in the main thread after ``seconds`` of wall time (SIGALRM; POSIX)."""

    def _fire(signum, frame):
        raise CaseTimeout(f"still running after {seconds:g} s")

    old = signal.signal(signal.SIGALRM, _fire)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)
