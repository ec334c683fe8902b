"""A trial asked for an execution provider this onnxruntime lacks runs on the CPU and says so."""

import onnxruntime as ort
import pytest

from eval.cli.main import main

pytestmark = pytest.mark.slow  # every test here builds a simulation, renders or runs the CLI


@pytest.mark.skipif("CUDAExecutionProvider" in ort.get_available_providers(), reason="this onnxruntime has CUDA")
def test_missing_cuda_runs_on_the_cpu_with_one_line(tmp_path, capsys):
    providers = "detector.providers=[CUDAExecutionProvider, CPUExecutionProvider]"
    args = ["run", "--max-frames", "5", "--quiet", "--no-video", "--set", providers, "--out", str(tmp_path / "t")]
    assert main(args) == 0
    lines = [line for line in capsys.readouterr().err.splitlines() if "ExecutionProvider" in line]
    assert lines == [
        "note: detector: CUDAExecutionProvider is not available in this onnxruntime "
        f"{ort.__version__} (it has {', '.join(ort.get_available_providers())}); running on CPUExecutionProvider"
    ]
