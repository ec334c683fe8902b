"""Progress bars only on a terminal, made in one place (eval/progress.py)."""

import io
import re
from pathlib import Path

from eval.progress import progress_bar

ROOT = Path(__file__).resolve().parents[2]


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_a_bar_is_written_on_a_terminal_only_and_quiet_turns_it_off():
    log, tty, quiet_tty = io.StringIO(), _Terminal(), _Terminal()
    for out, quiet in ((log, False), (tty, False), (quiet_tty, True)):
        assert sum(progress_bar(range(950), desc="trial", file=out, quiet=quiet)) == sum(range(950))
    assert log.getvalue() == ""  # a CI log: was ~950 bar updates a trial without --quiet
    assert "trial" in tty.getvalue() and "950/950" in tty.getvalue()
    assert quiet_tty.getvalue() == ""


def test_a_bar_updated_by_hand_and_stderr_by_default(capsys):
    with progress_bar(total=3, desc="dataset") as bar:  # pytest's stderr is no terminal
        bar.update(3)
    assert capsys.readouterr().err == ""


def test_tqdm_is_used_nowhere_else():
    uses = [
        str(p.relative_to(ROOT))
        for top in ("eval", "poi", "sim", "maze_assets", "bench")
        for p in (ROOT / top).rglob("*.py")
        if re.search(r"^\s*(from tqdm|import tqdm)", p.read_text(encoding="utf-8"), re.M)
    ]
    assert uses == ["eval/progress.py"]
