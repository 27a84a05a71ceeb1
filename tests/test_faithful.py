"""Minimal faithful window length from iterated models (Buenner et al. sec. IV)."""

import numpy as np
import pytest

from skdelay._faithful import THRESHOLDS
from skdelay.dynamics import minimal_embedding


@pytest.fixture(scope="module")
def mg17():
    from skdelay.systems import MackeyGlass, measure

    x = MackeyGlass(tau=17.0).simulate(20_000, random_state=0)
    return measure(x, noise=0.005, random_state=1)


@pytest.fixture(scope="module")
def table(mg17):
    return minimal_embedding(mg17, tau=17, m_max=4, n_steps=10_000, random_state=0)


def test_table_layout(table):
    tab, _m_d = table
    assert list(tab.index) == [1, 2, 3, 4] and tab.index.name == "m"
    for col in ("tau", "bounded", "hist_distance", "hist_ref", "spectrum_distance",
                "spectrum_ref", "chi", "chi_ref", "lambda_1", "d_ky", "h_ks", "n_positive",
                "lyap_change", "faithful"):
        assert col in tab
    assert (tab["tau"] == 17).all() and tab["bounded"].all()
    assert tab.loc[4, "lyap_change"] == 0.0


def test_scalar_window_is_not_faithful_but_m2_to_4_are_close(table):
    tab, m_d = table
    # m = 1 distorts the invariant measure and roughly doubles lambda_1 of Mackey-Glass
    assert tab.loc[1, "hist_distance"] > THRESHOLDS["histogram"] * tab.loc[1, "hist_ref"]
    assert tab.loc[1, "chi"] > 2 * tab.loc[1, "chi_ref"]
    assert tab.loc[1, "lyap_change"] > 0.5
    assert not tab.loc[1, "faithful"]
    # m >= 2: data-like histogram, cross-prediction close to chi(X, X), lambda_1 ~ 0.0052
    for m in (2, 3, 4):
        assert tab.loc[m, "hist_distance"] < 2 * tab.loc[m, "hist_ref"]
        assert tab.loc[m, "chi"] < 1.5 * tab.loc[m, "chi_ref"]
        assert 0.0035 < tab.loc[m, "lambda_1"] < 0.0065
        assert 1.9 < tab.loc[m, "d_ky"] < 2.3
    assert m_d in (2, 3, 4)
    assert tab.loc[m_d, "faithful"] and not tab.loc[:m_d - 1, "faithful"].any()


def test_tau_per_m_and_errors(mg17):
    with pytest.raises(ValueError, match="no delay for m"):
        minimal_embedding(mg17, tau={1: 17}, m_max=2)
    with pytest.raises(ValueError, match="unknown threshold"):
        minimal_embedding(mg17, tau=17, m_max=2, thresholds={"hist": 1.0})
    with pytest.raises(ValueError, match="needs at least"):
        minimal_embedding(mg17[:300], tau=100, m_max=2)
    tab, _ = minimal_embedding(mg17[:8000], tau={1: 16, 2: 17}, m_max=2, n_steps=3000,
                               random_state=1)
    assert tab["tau"].tolist() == [16, 17]
    assert np.isfinite(tab["chi"]).all()


def test_default_delays_from_forecast_error_scan(mg17):
    tab, _ = minimal_embedding(mg17[:10_000], tau_grid=range(10, 25), m_min=2, m_max=3,
                               n_steps=3000, random_state=0)
    assert tab["tau"].between(16, 18).all()
