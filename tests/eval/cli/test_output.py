"""``--out`` is checked before any command starts: a file, a path under a file or an unwritable
folder is one line naming the path, at once."""

import argparse
import errno
import os

import pytest

from eval.cli import output
from eval.cli.main import main
from eval.cli.output import OutputPathError, check_output_file, check_output_folder

# every command that takes --out, with its other required arguments
COMMANDS = [
    ["run"],
    ["render"],
    ["dataset", "--images", "4"],
    ["train", "--data", "d"],
    ["train-labels", "--data", "d"],
    ["evaluate-detector", "--model", "m.onnx"],
    ["suite", "run", "smoke"],
    ["sweep", "--suite", "smoke", "--set", "tracker.gate=3,4"],
    ["regress", "--baseline", "b.json"],
    ["tune", "--param", "tracker.gate=float:2:5"],
]


@pytest.mark.parametrize("argv", COMMANDS, ids=lambda a: a[0] if a[0] != "suite" else "suite-run")
def test_every_command_refuses_a_file_as_its_output_folder_before_it_starts(argv, tmp_path, monkeypatch, capsys):
    started = []
    parse_args = argparse.ArgumentParser.parse_args

    def parse_and_watch(self, *a, **kw):
        args = parse_args(self, *a, **kw)
        args.func = started.append  # the command itself: it must not run
        return args

    monkeypatch.setattr(argparse.ArgumentParser, "parse_args", parse_and_watch)
    afile = tmp_path / "taken"
    afile.write_text("x")
    assert main([*argv, "--out", str(afile)]) == 2
    assert started == []
    err = capsys.readouterr().err.strip()
    command = " ".join(argv[:2]) if argv[0] == "suite" else argv[0]  # a subcommand is named with its command
    assert err == f"poibench {command}: error: --out {afile}: is a file, not a folder"


@pytest.mark.parametrize("argv", [["run"], ["calibrate", "--model", "m.onnx"]], ids=["folder", "file"])
def test_an_empty_output_path_is_refused_not_taken_for_the_current_folder(argv, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main([*argv, "--out", ""]) == 2
    want = "give a folder" if argv[0] == "run" else "give a file name"
    err = capsys.readouterr().err.strip()
    assert err == f"poibench {argv[0]}: error: --out: an empty path (an unset shell variable?); {want}"
    assert list(tmp_path.iterdir()) == []


def test_a_folder_under_a_file_and_the_calibration_file(tmp_path, capsys):
    afile = tmp_path / "taken"
    afile.write_text("x")
    assert main(["run", "--out", str(afile / "trial")]) == 2
    assert f"--out {afile / 'trial'}: cannot make it, {afile} is a file" in capsys.readouterr().err
    calibrate = ["calibrate", "--model", "m.onnx", "--out"]
    assert main([*calibrate, str(tmp_path)]) == 2
    assert f"--out {tmp_path}: is a folder; give a file name" in capsys.readouterr().err
    assert main([*calibrate, str(afile / "cal.yaml")]) == 2
    assert f"{afile}: is a file, not a folder" in capsys.readouterr().err


def test_a_writable_or_makeable_folder_passes_and_nothing_is_made(tmp_path):
    check_output_folder(tmp_path)
    check_output_folder(tmp_path / "new" / "deeper")
    check_output_file(tmp_path / "new" / "cal.yaml")
    assert list(tmp_path.iterdir()) == []


def test_a_folder_that_cannot_be_written_names_the_reason(tmp_path, monkeypatch):
    def refuse(dir):
        raise PermissionError(errno.EACCES, os.strerror(errno.EACCES), str(dir))

    monkeypatch.setattr(output.tempfile, "TemporaryFile", refuse)
    with pytest.raises(OutputPathError, match=rf"^--out {tmp_path}: cannot write in it \(Permission denied\)$"):
        check_output_folder(tmp_path)
    new = tmp_path / "new"
    with pytest.raises(
        OutputPathError, match=rf"^--out {new}: cannot make it in {tmp_path} \(Permission denied\)$"
    ):
        check_output_folder(new)


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes in a read-only folder")
def test_a_read_only_folder_is_refused(tmp_path, capsys):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    try:
        assert main(["run", "--out", str(ro)]) == 2
        assert f"--out {ro}: cannot write in it (Permission denied)" in capsys.readouterr().err
    finally:
        ro.chmod(0o755)
