"""The empirical ROP correction a rig file carries (sim.empirical): its Gaussian-process prediction against
scikit-learn's with the same kernel, its rig-file round trip, and one clear line for a bad entry."""
from __future__ import annotations

import numpy as np
import pytest

import sim
from sim.empirical import LABEL, EmpiricalCorrection
from sim.models.param import ParameterError

POINTS = ((150.0, 900.0), (230.0, 900.0), (310.0, 900.0), (390.0, 900.0), (190.0, 1500.0), (270.0, 1500.0),
          (350.0, 1500.0), (430.0, 1500.0))
VALUES = (-0.005, -0.066, -0.071, -0.035, 0.078, 0.044, 0.005, 0.025)


def correction(**kw) -> EmpiricalCorrection:
    args = dict(inputs=("frequency_hz", "static_force_n"), lower=(150.0, 900.0), upper=(430.0, 1500.0),
                points=POINTS, values=VALUES, mean=-0.003, length_scales=(0.37, 0.6), signal_sd=0.05, noise_sd=0.01,
                floor_m_s=1e-4, basis="test")
    return EmpiricalCorrection(**{**args, **kw})


def test_prediction_is_scikit_learns_gaussian_process():
    """The numpy evaluation from the stored hyperparameters equals scikit-learn's GaussianProcessRegressor with the
    same kernel (constant x ARD RBF + white, not refitted) on the same scaled inputs, mean and sd (noise included)."""
    from sklearn.gaussian_process import GaussianProcessRegressor
    from sklearn.gaussian_process.kernels import RBF, ConstantKernel, WhiteKernel

    c = correction()
    lo, hi = np.array(c.lower), np.array(c.upper)
    x = (np.array(POINTS) - lo) / (hi - lo)
    kernel = ConstantKernel(c.signal_sd ** 2) * RBF(np.array(c.length_scales)) + WhiteKernel(c.noise_sd ** 2)
    gp = GaussianProcessRegressor(kernel, optimizer=None, normalize_y=False).fit(x, np.array(VALUES) - c.mean)
    q = np.array([[200.0, 1000.0], [300.0, 1200.0], [100.0, 2000.0], [430.0, 1500.0]])
    mu_ref, sd_ref = gp.predict((q - lo) / (hi - lo), return_std=True)
    mu, sd = c.relative({"frequency_hz": q[:, 0], "static_force_n": q[:, 1]})
    np.testing.assert_allclose(mu, mu_ref + c.mean, rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(sd, sd_ref, rtol=1e-6, atol=1e-9)


def test_correct_scales_the_relative_discrepancy_by_the_model_rop_or_its_floor():
    c = correction(noise_sd=0.0)
    rop = np.array([2e-3, 1e-5])          # the second below the floor: the discrepancy is relative to the floor
    fixed, sd = c.correct(rop, {"frequency_hz": [230.0, 230.0], "static_force_n": [900.0, 900.0]})
    mu, s = c.relative({"frequency_hz": [230.0], "static_force_n": [900.0]})
    assert mu[0] == pytest.approx(VALUES[1], abs=1e-6)       # noise-free: through its point
    np.testing.assert_allclose(fixed, [2e-3 * (1 + mu[0]), 1e-5 + mu[0] * 1e-4])
    np.testing.assert_allclose(sd, [2e-3 * s[0], 1e-4 * s[0]])


def test_far_from_the_runs_it_returns_to_its_mean_with_its_full_sd():
    c = correction()
    mu, sd = c.relative({"frequency_hz": [5000.0], "static_force_n": [900.0]})
    assert mu[0] == pytest.approx(c.mean, abs=1e-9)
    assert sd[0] == pytest.approx(np.hypot(c.signal_sd, c.noise_sd), rel=1e-9)


def test_a_rig_carries_it_through_its_file_mapping():
    rig = sim.Rig("drill", "lab", parameters={"K1": 5.4e8}, empirical=correction())
    m = rig.to_mapping()
    assert m["empirical_correction"]["label"] == LABEL
    back = sim.Rig.from_mapping(m)
    assert back.empirical == rig.empirical
    assert back.with_values({"K1": 5e8}).empirical == rig.empirical


@pytest.mark.parametrize("change, culprit", [
    ({"noise_sdd": 0.1}, "unknown empirical_correction key 'noise_sdd' (did you mean noise_sd?)"),
    ({"values": [0.1, 0.2]}, "empirical_correction values must be 8 finite numbers"),
    ({"signal_sd": -1.0}, "empirical_correction signal_sd must be > 0"),
    ({"length_scales": [0.3, "x"]}, "empirical_correction length_scales must be a list of numbers"),
    ({"upper": [150.0, 1500.0]}, "upper > lower"),
    ({"target": "power_w"}, "target must be rop_m_s"),
])
def test_a_bad_entry_is_one_line_naming_it(change, culprit):
    m = {**correction().to_mapping(), **change}
    if "noise_sdd" in change:
        m.pop("noise_sd")
    with pytest.raises(ParameterError) as e:
        sim.Rig.from_mapping({"model": "drill", "preset": "lab", "empirical_correction": m})
    assert culprit in str(e.value) and "\n" not in str(e.value)


def test_a_missing_input_is_named():
    with pytest.raises(ParameterError, match="needs static_force_n"):
        correction().relative({"frequency_hz": [200.0]})


def test_a_point_that_does_not_progress_stays_so_and_rop_never_turns_negative():
    c = correction(values=tuple(-3.0 for _ in VALUES), mean=-3.0, noise_sd=0.0)    # a -300 % discrepancy
    fixed, sd = c.correct([0.0, 2e-3], {"frequency_hz": [230.0, 230.0], "static_force_n": [900.0, 900.0]})
    assert fixed.tolist() == [0.0, 0.0] and sd[0] == 0.0 and sd[1] >= 0.0


def test_correct_inverts_the_discrepancy_it_is_fitted_to():
    """A correction that predicts a run's own discrepancy exactly (no noise) gives back the measured ROP there."""
    c = correction(noise_sd=0.0, values=tuple(EmpiricalCorrection.discrepancy(
        [2.2e-3] * 8, [2e-3] * 8, 1e-4).tolist()), mean=0.1)
    fixed, _ = c.correct([2e-3], {"frequency_hz": [230.0], "static_force_n": [900.0]})
    assert fixed[0] == pytest.approx(2.2e-3, rel=1e-9)
