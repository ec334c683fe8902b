"""An ``--out`` folder another live run writes in is refused with one line; a lock left by a
run that has ended is taken over; the lock goes when the run ends."""

import os
import subprocess
import sys

import pytest

from eval.cli import output
from eval.cli.main import main
from eval.cli.output import LOCK_NAME, OutputFolderBusyError, hold_output_folder

HOLD = (
    "import sys\n"
    "from eval.cli.output import hold_output_folder\n"
    "with hold_output_folder(sys.argv[1]):\n"
    "    print('held', flush=True)\n"
    "    sys.stdin.read()\n"
)


@pytest.fixture
def other_run(tmp_path):
    """A second process holding tmp_path / 'trial' until the test ends."""
    folder = tmp_path / "trial"
    proc = subprocess.Popen(
        [sys.executable, "-c", HOLD, str(folder)], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True
    )
    assert proc.stdout.readline().strip() == "held"
    yield folder, proc.pid
    proc.communicate("", timeout=30)
    assert not (folder / LOCK_NAME).exists()  # released when it ended


@pytest.mark.parametrize("command", [["run"], ["replay", "rec.mcap"]])
def test_a_second_run_into_a_held_folder_is_refused_before_it_starts(command, other_run, monkeypatch, capsys):
    folder, pid = other_run
    started = []
    monkeypatch.setattr("eval.cli.run.cmd_run", lambda args: started.append(args) or 0)
    monkeypatch.setattr("eval.cli.replay.cmd_replay", lambda args: started.append(args) or 0)
    assert main([*command, "--out", str(folder)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and not started
    assert f"--out {folder}: another poibench run (pid {pid}) is writing in it" in err


def test_the_lock_is_held_while_the_command_runs_and_gone_after(tmp_path, monkeypatch):
    folder = tmp_path / "trial"
    seen = []
    monkeypatch.setattr(
        "eval.cli.run.cmd_run", lambda args: seen.append((folder / LOCK_NAME).read_text().split()[0]) or 0
    )
    assert main(["run", "--out", str(folder)]) == 0
    assert seen == [str(os.getpid())]
    # nothing left: no lock, no temporary file, and the folder the lock made is gone again
    assert not folder.exists()
    folder.mkdir()
    assert main(["run", "--out", str(folder)]) == 0
    assert sorted(p.name for p in folder.iterdir()) == []  # a folder that was there stays


def test_a_lock_of_a_process_that_has_ended_is_taken_over(tmp_path):
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    (tmp_path / LOCK_NAME).write_text(f"{int(dead.stdout)} 1\n")
    with hold_output_folder(tmp_path):
        assert (tmp_path / LOCK_NAME).read_text().split()[0] == str(os.getpid())
    assert not (tmp_path / LOCK_NAME).exists()


@pytest.mark.parametrize("content", ["", "garbled\n", "-4 0\n"])
def test_a_garbled_lock_is_stale(tmp_path, content):
    (tmp_path / LOCK_NAME).write_text(content)
    with hold_output_folder(tmp_path):
        pass
    assert not (tmp_path / LOCK_NAME).exists()


def test_a_lock_with_this_pid_not_held_here_is_a_leftover_and_a_reused_pid_is_not_its_holder(tmp_path):
    # a container's run gets the same pid each time: its own pid in an old lock is a leftover
    (tmp_path / LOCK_NAME).write_text(f"{os.getpid()} {output._start_time(os.getpid())}\n")
    # taken over; held here now, a second hold in this process is refused
    with hold_output_folder(tmp_path), pytest.raises(OutputFolderBusyError), hold_output_folder(tmp_path):
        pass
    assert not (tmp_path / LOCK_NAME).exists()
    # a live pid whose start time differs from the lock's: the pid was reused, the lock is stale
    parent = os.getppid()
    if output._start_time(parent):
        (tmp_path / LOCK_NAME).write_text(f"{parent} 1\n")
        with hold_output_folder(tmp_path):
            assert (tmp_path / LOCK_NAME).read_text().split()[0] == str(os.getpid())
