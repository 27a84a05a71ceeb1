"""The named parameter sets of CO2LaserFeedback (issue 12, benchmarks/laser_regime.py)."""

import numpy as np
import pytest
from scipy.signal import welch

from skdelay.systems import CO2LaserFeedback

SEED = 1  # the seed of the scan (periodic windows lie close by at tau = 50)


def test_buenner_preset_is_the_default_and_presets_override():
    assert CO2LaserFeedback.from_preset("buenner2000", tau=50.0) == CO2LaserFeedback(tau=50.0)
    old = CO2LaserFeedback.from_preset("pisarchik2001", tau=50.0)
    assert (old.params["r"], old.params["b0"]) == (160.0, 0.1031)
    laser = CO2LaserFeedback.from_preset("buenner2000", tau=400.0, sp=1e-5)
    assert laser.params["tau"] == 400.0 and laser.params["sp"] == 1e-5
    for key, value in CO2LaserFeedback.PRESETS["buenner2000"].items():
        if key != "sp":
            assert laser.params[key] == value
    with pytest.raises(ValueError, match="valid names: buenner2000, pisarchik2001"):
        CO2LaserFeedback.from_preset("arecchi")


def test_buenner_preset_oscillates_near_25us_and_is_weakly_chaotic_at_tau_50():
    laser = CO2LaserFeedback.from_preset("buenner2000", tau=50.0)
    x = laser.simulate(20_000, random_state=SEED)
    f, psd = welch(x - x.mean(), nperseg=2048)
    # the Hopf band of the loop: the power between 15 and 40 us dominates the
    # delay modulation (50 us) and its harmonics outside that band
    hopf = (f > 1 / 40) & (f < 1 / 15)
    assert psd[hopf].sum() > 0.5 * psd[f > 1 / 100].sum()
    # the paper's low-dimensional case: one (at most two) positive exponents of
    # a few per ms; the published defaults have 4-5 and lambda_max ~ 7 per ms
    spec = laser.lyapunov_spectrum(6, duration=10_000, random_state=SEED)
    lam = spec.exponents.copy()
    lam[np.argmin(np.abs(lam))] = 0.0  # the flow's zero exponent
    n_positive = int(np.sum(lam > spec.spread))
    assert 1 <= n_positive <= 2, spec.exponents
    assert 0.8e-3 < spec.exponents[0] < 5e-3, spec.exponents
