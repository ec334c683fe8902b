"""poi.core.sensor_noise: one depth-noise formula and one centre-noise default for sim and pipeline."""

import numpy as np
import pytest

from poi.config import load_config
from poi.core.sensor_noise import CENTER_SIGMA_A_PX, CENTER_SIGMA_B, depth_sigma_m, window_correlation
from sim.oracle import OracleSettings
from sim.scenario import load_scenario
from sim.sensors.d435_depth import window_noise

DEPTHS_M = (0.5, 1.0, 2.0, 4.0)


def test_depth_sigma_is_intels_rms_error_formula():
    # RMS error = z^2 * subpixel / (f * B): at 4 m, f = 384.2 px, B = 50 mm, 0.08 px
    # -> 16 * 0.08 / 19.21 = 0.066632 m; at 0.5 m a 64th of that
    assert depth_sigma_m(4.0, sigma_d_px=0.08, fx_depth_px=384.2, baseline_m=0.05) == pytest.approx(
        16 * 0.08 / 19.21, rel=1e-12
    )
    assert depth_sigma_m(0.5, sigma_d_px=0.08, fx_depth_px=384.2, baseline_m=0.05) == pytest.approx(
        0.066632 / 64, rel=1e-4
    )
    z = np.array(DEPTHS_M)
    got = depth_sigma_m(z, sigma_d_px=0.1, fx_depth_px=400.0, baseline_m=0.05)  # f B = 20 px m
    assert np.allclose(got, [0.00125, 0.005, 0.02, 0.08], rtol=1e-12)


def test_pipeline_default_depth_noise_equals_the_simulators():
    spec = load_scenario("default").sensors.d435.depth
    lc = load_config().localize
    for z in DEPTHS_M:
        sim_sigma = depth_sigma_m(
            z, sigma_d_px=spec.sigma_d_px, fx_depth_px=spec.fx_depth_px, baseline_m=spec.baseline_m
        )
        poi_sigma = depth_sigma_m(
            z, sigma_d_px=lc.sigma_d_px, fx_depth_px=lc.fx_depth_px, baseline_m=lc.baseline_m
        )
        assert poi_sigma == sim_sigma, z


def test_oracle_centre_noise_defaults_are_the_pipelines():
    oracle = OracleSettings()
    shipped = load_config().localize.center_sigma_px  # poi/configs/default.yaml
    assert (oracle.center_sigma_a_px, oracle.center_sigma_b) == (CENTER_SIGMA_A_PX, CENTER_SIGMA_B)
    assert (shipped.a_px, shipped.b) == (CENTER_SIGMA_A_PX, CENTER_SIGMA_B)


@pytest.mark.parametrize("step", [1, 3])
def test_window_correlation_is_the_simulators_depth_noise_correlation(step):
    """The simulator's window-correlated depth noise (7 px window) correlates between pixels
    k step apart along a row and along a column as window_correlation says, within 0.02
    (a 400 x 400 image: 160000 pairs a lag), and not at all beyond the window."""
    rng = np.random.default_rng(step)
    e = window_noise(rng.standard_normal((406, 406), np.float32), 7).astype(np.float64)
    rho = window_correlation(7, step)
    k_max = rho.size // 2
    for k in range(1, k_max + 2):
        lag = k * step
        along_row = np.mean(e[:, :-lag] * e[:, lag:]) / np.mean(e * e)
        along_col = np.mean(e[:-lag, :] * e[lag:, :]) / np.mean(e * e)
        expected = rho[k_max + k] if k <= k_max else 0.0
        assert along_row == pytest.approx(expected, abs=0.02), lag
        assert along_col == pytest.approx(expected, abs=0.02), lag


def test_window_correlation_refuses_a_zero_window():
    with pytest.raises(ValueError, match="window_px >= 1"):
        window_correlation(0)
