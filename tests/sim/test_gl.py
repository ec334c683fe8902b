"""sim.gl: the headless backend's llvmpipe flags, and the same frames and detections on another CPU.

The cross-CPU test renders two frames of the default tour and runs the shipped detector on one,
natively and under ``qemu-x86_64 -cpu Haswell`` (an AVX2 CPU without AVX-512 or VNNI; qemu
computes approximate instructions such as ``rsqrtps`` exactly, as no real CPU does, so it is a
stricter check than another real machine), and wants the same bytes. It needs qemu-user
(``apt-get install qemu-user``; .ci/run installs it) on an x86-64 host, and is skipped elsewhere.
"""

from __future__ import annotations

import os
import platform
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from sim.gl import GALLIVM_PERF_PORTABLE

ROOT = Path(__file__).resolve().parents[2]

FRAMES_SCRIPT = textwrap.dedent(
    """
    import sys
    import numpy as np
    from poi.models import model_file
    from poi.detectors.onnx_yolo import OnnxYoloDetector
    from sim.scenario import load_scenario
    from sim.simulator import Simulation

    out = {}
    with Simulation(load_scenario("default")) as sim:
        frames = {k: sim.frame(k) for k in (0, 37)}
    for k, (frame, truth) in frames.items():
        out[f"rgb{k}"], out[f"depth{k}"] = frame.rgb, frame.depth_m
        out[f"thermal{k}"], out[f"mask{k}"] = frame.thermal_c, truth.object_mask
    model = model_file("default")
    det = OnnxYoloDetector(model=model, conf=0.05, label_model=model.with_name("default_labels.onnx"))
    found = det.detect(frames[37][0])
    out["boxes"] = np.array([d.box_xyxy for d in found], np.float64).reshape(-1, 4)
    out["scores"] = np.array([d.confidence for d in found], np.float64)
    out["classes"] = np.array([d.class_name for d in found])
    np.savez(sys.argv[1], **out)
    """
)


def _env() -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k != "GALLIVM_PERF"}
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), env.get("PYTHONPATH", "")])
    env.setdefault("MUJOCO_GL", "egl")
    return env


def test_the_backend_asks_llvmpipe_for_its_portable_texture_path():
    env = _env() | {"MUJOCO_GL": "egl", "GALLIVM_PERF": "brilinear"}
    code = "import os, sim.gl; print(os.environ['GALLIVM_PERF'])"
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    assert out.stdout.split() == [f"brilinear,{GALLIVM_PERF_PORTABLE}"]


@pytest.mark.slow
@pytest.mark.skipif(
    platform.machine() not in ("x86_64", "AMD64") or shutil.which("qemu-x86_64") is None,
    reason="needs an x86-64 host with qemu-user (qemu-x86_64)",
)
def test_frames_and_detections_are_the_same_on_an_avx2_cpu(tmp_path):
    script = tmp_path / "frames.py"
    script.write_text(FRAMES_SCRIPT)
    native, emulated = tmp_path / "native.npz", tmp_path / "haswell.npz"
    python = os.path.realpath(sys.executable)  # qemu runs the interpreter itself, not a wrapper script
    subprocess.run([python, str(script), str(native)], env=_env(), check=True, timeout=300)
    subprocess.run(
        ["qemu-x86_64", "-cpu", "Haswell", python, str(script), str(emulated)],
        env=_env(),
        check=True,
        timeout=900,
        stderr=subprocess.DEVNULL,  # qemu's warnings about CPU features it does not emulate
    )
    a, b = np.load(native), np.load(emulated)
    assert sorted(a.files) == sorted(b.files)
    assert len(a["boxes"]) >= 3  # the detector found something to compare
    for name in a.files:
        assert a[name].dtype == b[name].dtype and np.array_equal(a[name], b[name]), name
