"""The ``poibench`` entry point: a Ctrl-C at any point is one line and exit status 130."""

import pytest

from eval.cli import main as cli


@pytest.mark.parametrize("when", ["start-up", "command"])
def test_ctrl_c_is_one_line(when, monkeypatch, capsys):
    def interrupt(*args, **kwargs):
        raise KeyboardInterrupt

    if when == "start-up":  # while the command modules are imported
        monkeypatch.setattr(cli, "build_parser", interrupt)
        expected = "poibench: interrupted"
    else:
        monkeypatch.setattr("eval.cli.score.run", interrupt)
        expected = "poibench score: interrupted"
    assert cli.main(["score", "r.csv", "--truth", "t.csv"]) == 130
    assert capsys.readouterr().err == expected + "\n"


class _NoEGL:
    """mujoco.GLContext where Mesa's EGL is missing: MuJoCo's placeholder raises ImportError."""

    def __init__(self, *args, **kwargs):
        raise ImportError(
            "Failed to import OpenGL backend (MUJOCO_GL='egl'): libEGL.so.1: cannot open shared object file"
        )


@pytest.mark.slow  # builds a simulation (its first render is where the GL context fails)
def test_missing_gl_backend_is_one_line_that_says_what_to_install(monkeypatch, capsys, tmp_path):
    import mujoco

    monkeypatch.setattr(mujoco, "GLContext", _NoEGL)
    argv = [
        "run",
        "--max-frames",
        "1",
        "--no-video",
        "--quiet",
        "--detector",
        "oracle",
        "--out",
        str(tmp_path / "t"),
    ]
    assert cli.main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err
    assert err.startswith("poibench run: error: headless rendering failed with MUJOCO_GL="), err
    assert "(ImportError: Failed to import OpenGL backend (MUJOCO_GL='egl'): libEGL.so.1" in err
    assert (
        "install Mesa's EGL (apt-get install libegl1 libgl1-mesa-dri) or OSMesa (apt-get install libosmesa6)"
        in err
    )


def test_suite_list_names_each_shipped_suite_under_a_header(capsys):
    from eval.experiments.suites import load_suite, shipped_suites

    assert cli.main(["suite", "list"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].split() == ["suite", "version", "scenarios", "what", "it", "holds"]
    for name, line in zip(shipped_suites(), lines[1:], strict=False):
        s = load_suite(name)
        assert line.split()[:3] == [name, f"v{s.version}", str(len(s.scenarios))]
    assert lines[-1].startswith("poibench suite run NAME runs one")
