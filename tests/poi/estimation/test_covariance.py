"""poi.estimation.covariance: J1, J2, Sigma_c, R ([Avevor2022]_ 2.2.2, 2.3.2), centre-error model, calibration.

References
----------
Full entries in docs/SOURCES.md.

.. [Avevor2022] E. Avevor, "Proposed solution to RoboCupRescue EX3", University of Cambridge,
   2022.
"""

from __future__ import annotations

import numpy as np
import pytest
import yaml

from poi.core.geometry import R_BODY_OPTICAL, rot_z
from poi.core.names import ARENA_TYPES, CLASS_INDEX, CLASSES, RESCUE_CLASSES
from poi.core.types import Intrinsics
from poi.estimation.covariance import (
    CalibrationError,
    camera_covariance,
    center_sigmas_px,
    deprojection_jacobian,
    depth_jacobian,
    load_calibration,
    map_covariance,
)
from poi.estimation.projection import deproject_pixel_to_point

# A plane tilted in the image: d = 2 + 0.1 col + 0.2 row (metres).
ROWS, COLS = np.mgrid[0:5, 0:6]
RAMP = 2.0 + 0.1 * COLS + 0.2 * ROWS


def test_j1_central_differences():
    J1 = depth_jacobian(RAMP, 2, 3)
    # 0.5 (d(u+1) - d(u-1)) = 0.5 * 0.2 = 0.1 per px along u; 0.2 per px along v
    assert np.allclose(J1, [[1, 0, 0], [0, 1, 0], [0.1, 0.2, 1]], rtol=0, atol=1e-12)
    # the pixel coordinate is rounded to the nearest pixel
    assert np.allclose(depth_jacobian(RAMP, 2.4, 2.6), J1)
    # depth_scale multiplies the gradient (d' is the scaled depth)
    assert depth_jacobian(RAMP, 2, 3, depth_scale=1.04)[2, 0] == pytest.approx(0.104)


def test_j1_border_is_one_sided_and_invalid_neighbours_give_zero():
    # at u = 0 the left neighbour is clamped: (d(1) - d(0)) / 1 = 0.1, not halved
    assert depth_jacobian(RAMP, 0, 2)[2, :2] == pytest.approx([0.1, 0.2])
    assert depth_jacobian(RAMP, 5, 4)[2, :2] == pytest.approx([0.1, 0.2])
    d = RAMP.copy()
    d[2, 3] = 0.0  # right neighbour of (u=2, v=2) invalid
    d[1, 2] = np.nan  # upper neighbour invalid
    assert depth_jacobian(d, 2, 2)[2, :2].tolist() == [0.0, 0.0]
    one_px = np.array([[2.0]])
    assert depth_jacobian(one_px, 0, 0)[2, :2].tolist() == [0.0, 0.0]


def test_j2_numeric_equals_analytic_for_model_none():
    k = Intrinsics(width=640, height=480, fx=612.4, fy=610.6, ppx=314.3, ppy=237.8)
    u, v, d = 500.0, 100.0, 3.0
    J2 = deprojection_jacobian(lambda a, b, c: deproject_pixel_to_point(k, a, b, c), u, v, d)
    analytic = np.array(
        [
            [d / k.fx, 0.0, (u - k.ppx) / k.fx],
            [0.0, d / k.fy, (v - k.ppy) / k.fy],
            [0.0, 0.0, 1.0],
        ]
    )
    # x = (u - ppx) d / fx is bilinear: central differences are exact up to rounding
    assert np.allclose(J2, analytic, rtol=0, atol=1e-9)


def test_sigma_c_hand_computed():
    # fx = fy = 500, principal point 0, pixel (100, 50), d = 2 m:
    # J2 = [[d/fx, 0, u/fx], [0, d/fy, v/fy], [0, 0, 1]]
    #    = [[0.004, 0, 0.2], [0, 0.004, 0.1], [0, 0, 1]]
    J2 = np.array([[0.004, 0.0, 0.2], [0.0, 0.004, 0.1], [0.0, 0.0, 1.0]])
    J1 = np.array([[1.0, 0, 0], [0, 1.0, 0], [0.01, 0.0, 1.0]])  # 1 cm per px along u
    Sigma_1 = np.diag([4.0, 1.0, 1e-4])  # sigma_u 2 px, sigma_v 1 px, sigma_d 1 cm
    Sigma_c = camera_covariance(J1, J2, Sigma_1)
    # Sigma_2 = J1 Sigma_1 J1^T = [[4, 0, 0.04], [0, 1, 0], [0.04, 0, 0.0005]]
    # Sigma_c[0,0] = 0.004^2*4 + 2*0.004*0.2*0.04 + 0.2^2*0.0005 = 6.4e-5 + 6.4e-5 + 2e-5
    assert Sigma_c[0, 0] == pytest.approx(1.48e-4, rel=1e-12)
    # Sigma_c[1,1] = 0.004^2*1 + 0.1^2*0.0005 = 1.6e-5 + 5e-6
    assert Sigma_c[1, 1] == pytest.approx(2.1e-5, rel=1e-12)
    assert Sigma_c[2, 2] == pytest.approx(5e-4, rel=1e-12)
    # Sigma_c[0,2] = 0.004*0.04 + 0.2*0.0005 = 1.6e-4 + 1e-4
    assert Sigma_c[0, 2] == pytest.approx(2.6e-4, rel=1e-12)
    # Sigma_c[0,1] = 0.2 * 0.1 * 0.0005 + 0.004 * 0.1 * 0.04 ... = 1e-5 + 1.6e-5
    assert Sigma_c[0, 1] == pytest.approx(2.6e-5, rel=1e-12)
    assert np.allclose(Sigma_c, Sigma_c.T)


def test_r_for_a_90_degree_rotation():
    Sigma_c = np.diag([1.0, 4.0, 9.0])
    # Q = rot_z(90 deg) swaps x and y variances; Sigma_eps = 0.1^2 I adds 0.01
    R = map_covariance(Sigma_c, rot_z(np.pi / 2), np.eye(3), 0.1)
    assert np.allclose(R, np.diag([4.01, 1.01, 9.01]), atol=1e-12)
    # with the optical-to-body mount: optical z (9) -> body x, x (1) -> y, y (4) -> z;
    # then rot_z(90): body x -> map y, body y -> map x
    R = map_covariance(Sigma_c, rot_z(np.pi / 2), R_BODY_OPTICAL, 0.0)
    assert np.allclose(R, np.diag([1.0, 9.0, 4.0]), atol=1e-12)


def _write(tmp_path, doc) -> str:
    p = tmp_path / "cal.yaml"
    p.write_text(yaml.safe_dump(doc))
    return str(p)


def _uniform_confusion() -> np.ndarray:
    C = len(CLASSES)
    M = np.full((C, C), 1.0 / (C - 1))
    np.fill_diagonal(M, 0.0)
    return M


def test_center_model_default_and_calibrated(tmp_path):
    assert center_sigmas_px("door", 100.0, 50.0, a_px=1.0, b=0.03) == (4.0, 2.5)
    path = _write(
        tmp_path,
        {
            "poibench_calibration": 1,
            "center_variance_px2": {
                "default": {"u": [1.0], "v": [2.0]},
                "door": {"u": [4.0, 0.1], "v": [1.0, 0.0, 0.01]},
            },
        },
    )
    cal = load_calibration(path)
    # door: sigma_u^2 = 4 + 0.1 * 100 = 14; sigma_v^2 = 1 + 0.01 * 50^2 = 26
    su, sv = center_sigmas_px("door", 100.0, 50.0, a_px=1.0, b=0.03, calibration=cal)
    assert (su, sv) == pytest.approx((np.sqrt(14.0), np.sqrt(26.0)))
    # other classes fall back to the file's default entry
    assert center_sigmas_px("valve", 100.0, 50.0, a_px=1.0, b=0.03, calibration=cal) == (
        pytest.approx(1.0),
        pytest.approx(np.sqrt(2.0)),
    )
    assert cal.confusion is None


def test_confusion_matrix_loaded_and_reordered(tmp_path):
    M = _uniform_confusion()
    M[0] = 0.0
    M[0, 1], M[0, 2] = 0.75, 0.25  # explosive is misread as blasting-agent or flammable-gas
    rev = list(reversed(CLASSES))
    idx = [CLASS_INDEX[c] for c in rev]
    path = _write(
        tmp_path,
        {
            "poibench_calibration": 1,
            "confusion": {"classes": rev, "matrix": M[np.ix_(idx, idx)].tolist()},
        },
    )
    cal = load_calibration(path)
    assert np.allclose(cal.confusion, M)


@pytest.mark.parametrize(
    ("doc", "message"),
    [
        ({"center_variance_px2": {}}, "poibench_calibration: expected 1"),
        ({"poibench_calibration": 1, "extra": 1}, "extra: unknown key"),
        (
            {"poibench_calibration": 1, "center_variance_px2": {"dor": {"u": [1], "v": [1]}}},
            "center_variance_px2.dor: unknown class",
        ),
        (
            {
                "poibench_calibration": 1,
                "center_variance_px2": {"door": {"u": [1, -0.1], "v": [1]}},
            },
            r"center_variance_px2.door.u: expected a non-empty list of coefficients >= 0",
        ),
        (
            {"poibench_calibration": 1, "center_variance_px2": {"door": {"u": [0.0], "v": [1]}}},
            "door.u: expected a constant term > 0",
        ),
        (
            {"poibench_calibration": 1, "confusion": {"matrix": [[0.0]]}},
            "confusion.matrix: expected a 24 x 24",
        ),
    ],
)
def test_calibration_errors_name_the_key(tmp_path, doc, message):
    with pytest.raises(CalibrationError, match=message):
        load_calibration(_write(tmp_path, doc))


def test_rescue_confusion_expands_to_all_classes_for_the_tracker(tmp_path):
    # what `poibench calibrate` writes for a rescue detector: 24 x 24 over RESCUE_CLASSES
    R = len(RESCUE_CLASSES)
    M = np.full((R, R), 1.0 / (R - 1))
    np.fill_diagonal(M, 0.0)
    ox, ex, fl = (RESCUE_CLASSES.index(c) for c in ("oxygen", "explosive", "flammable-gas"))
    M[ox] = 0.0
    M[ox, ex], M[ox, fl] = 10 / 11, 1 / 11
    doc = {"poibench_calibration": 1, "confusion": {"classes": list(RESCUE_CLASSES), "matrix": M.tolist()}}
    cal = load_calibration(_write(tmp_path, doc))
    C = len(CLASSES)
    assert cal.confusion.shape == (C, C)
    assert np.allclose(cal.confusion[:R, :R], M)  # rescue block unchanged (rescue indices are a prefix)
    assert np.all(cal.confusion[:R, R:] == 0.0)  # a rescue class is never misread as an arena class
    assert np.allclose(cal.confusion.sum(axis=1), 1.0) and np.all(np.diag(cal.confusion) == 0.0)
    # the tracker's p(actual B | detected A) = (1 - p) C[A, B], p on A: [Avevor2022] 2.1.5
    from poi.core.types import Detection, Observation
    from poi.estimation.tracker import observation_probs

    def q(class_name: str, p: float) -> np.ndarray:
        det = Detection(class_name=class_name, type=class_name, text="", box_xyxy=(0, 0, 1, 1), confidence=p)
        o = Observation(
            detection=det,
            timestamp_s=0.0,
            position_map=np.zeros(3),
            R=np.eye(3),
            position_cam=np.zeros(3),
            Sigma_c=np.eye(3),
            depth_m=1.0,
        )
        return observation_probs(o, "confusion", cal.confusion)

    for arena in ARENA_TYPES:  # not covered: its 1 - p spread evenly over the other C - 1 classes
        v = q(arena, 0.7)
        assert v[CLASS_INDEX[arena]] == pytest.approx(0.7) and v.sum() == pytest.approx(1.0)
        others = np.delete(v, CLASS_INDEX[arena])
        assert np.allclose(others, 0.3 / (C - 1))
    v = q("oxygen", 0.8)  # covered: the calibrated row, nothing on arena classes
    assert v[CLASS_INDEX["explosive"]] == pytest.approx(0.2 * 10 / 11) and v[R:].sum() == 0.0
    # without `classes`, a 24 x 24 matrix is read in RESCUE_CLASSES order
    cal2 = load_calibration(_write(tmp_path, {"poibench_calibration": 1, "confusion": {"matrix": M.tolist()}}))
    assert np.array_equal(cal2.confusion, cal.confusion)
    classes = list(RESCUE_CLASSES[:-1]) + ["ball"]
    bad = {"poibench_calibration": 1, "confusion": {"classes": classes, "matrix": M.tolist()}}
    with pytest.raises(CalibrationError, match="confusion.classes: expected each of the 24 names"):
        load_calibration(_write(tmp_path, bad))


def test_confusion_row_sum_and_diagonal_checked(tmp_path):
    M = _uniform_confusion()
    M[3, 5] += 0.1
    with pytest.raises(CalibrationError, match=r"row 3 \(non-flammable-gas\) sums to 1.1"):
        load_calibration(_write(tmp_path, {"poibench_calibration": 1, "confusion": {"matrix": M.tolist()}}))
    M = _uniform_confusion()
    M[2, 2] = 0.5
    with pytest.raises(CalibrationError, match="zero diagonal"):
        load_calibration(_write(tmp_path, {"poibench_calibration": 1, "confusion": {"matrix": M.tolist()}}))
    with pytest.raises(CalibrationError, match="cannot read calibration"):
        load_calibration(tmp_path / "missing.yaml")
