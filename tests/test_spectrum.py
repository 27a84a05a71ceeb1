import numpy as np
import pytest

from skdelay._spectrum import (
    LyapunovSpectrum,
    dimension_density,
    kaplan_yorke_dimension,
    ks_entropy,
    rescale_spectrum,
)


def test_kaplan_yorke_lorenz_and_henon():
    # Lorenz: (0.906, 0, -14.572) -> 2.062; Henon: (0.419, -1.623) -> 1.258
    assert kaplan_yorke_dimension([0.906, 0.0, -14.572]) == pytest.approx(2.0622, abs=1e-3)
    assert kaplan_yorke_dimension([-1.623, 0.419]) == pytest.approx(1.2582, abs=1e-3)


def test_kaplan_yorke_edge_cases():
    assert kaplan_yorke_dimension([-0.1, -0.2]) == 0.0
    # partial sums never turn negative: the spectrum is too short, D_KY >= n
    assert kaplan_yorke_dimension([0.3, 0.1, -0.2]) == 3.0
    with pytest.raises(ValueError, match="NaN"):
        kaplan_yorke_dimension([0.1, np.nan])
    with pytest.raises(ValueError, match="empty"):
        kaplan_yorke_dimension([])


def test_entropy_density_rescale():
    assert ks_entropy([0.2, 0.1, -0.5, 0.0]) == pytest.approx(0.3)
    assert dimension_density(23.8, 400) == pytest.approx(0.0595)
    x, y = rescale_spectrum([-0.03, 0.02, 0.01], 100)
    np.testing.assert_allclose(x, [0.01, 0.02, 0.03])
    np.testing.assert_allclose(y, [2.0, 1.0, -3.0])
    with pytest.raises(ValueError, match="positive delay"):
        rescale_spectrum([0.1], 0)


def test_spectrum_value_type_sorts_and_derives():
    s = LyapunovSpectrum([0.01, -0.5, 0.2], spread=[0.02, 0.01, 0.01], sample_dt=0.5)
    np.testing.assert_allclose(s.exponents, [0.2, 0.01, -0.5])
    np.testing.assert_allclose(s.spread, [0.01, 0.02, 0.01])
    assert s.n_positive == 1  # 0.01 is within its spread of zero
    np.testing.assert_allclose(s.per_step, [0.1, 0.005, -0.25])
    assert s.ks_entropy == pytest.approx(0.21)
    assert s.kaplan_yorke_dimension == pytest.approx(2 + 0.21 / 0.5)
    assert list(s.to_frame().columns) == ["exponent", "spread"]
