"""Tests of the generated, cached laser data sets."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

import skdelay
from skdelay import datasets
from skdelay.datasets import data_home, load_laser, load_laser_all
from skdelay.systems import CO2LaserFeedback


@pytest.fixture
def cache_dir(tmp_path, monkeypatch):
    path = tmp_path / "skdelay-cache"
    monkeypatch.setenv("SKDELAY_DATA", str(path))
    return path


def test_load_laser_is_deterministic_cached_and_outside_the_package(cache_dir):
    first = load_laser(50, n_samples=5000)
    files = sorted(cache_dir.glob("*.npy"))
    assert len(files) == 1 and files[0].name.startswith("laser_tau50_n5000_")
    package = Path(skdelay.__file__).resolve().parent
    assert package not in files[0].resolve().parents
    assert not [p for p in cache_dir.iterdir() if p.suffix == ".tmp"]  # nothing half-written
    raw = files[0].read_bytes()
    again = load_laser(50, n_samples=5000)  # from the cache
    np.testing.assert_array_equal(first.series, again.series)
    files[0].unlink()
    regenerated = load_laser(50, n_samples=5000)  # same bytes when generated anew
    assert files[0].read_bytes() == raw
    np.testing.assert_array_equal(first.series, regenerated.series)
    fresh = load_laser(50, n_samples=5000, cache=False)
    np.testing.assert_array_equal(first.series, fresh.series)


def test_load_laser_bunch_contents(cache_dir):
    data = load_laser(150, n_samples=4000, cache=False)
    assert set(data) >= {"series", "sample_dt", "delay", "delay_samples", "system", "description"}
    y = data.series
    assert y.dtype == np.float64 and y.shape == (4000,)
    assert abs(y.mean()) < 1e-12 and np.mean(y**2) == pytest.approx(1.0)
    # 12-bit ADC: at most 4096 distinct levels, equally spaced
    levels = np.unique(y)
    assert 100 < levels.size <= 4096
    steps = np.diff(levels)
    np.testing.assert_allclose(steps / steps.min(), np.round(steps / steps.min()), atol=1e-6)
    assert data.sample_dt == 1.0 and data.delay == 150.0 and data.delay_samples == 150
    assert isinstance(data.system, CO2LaserFeedback) and data.system.params["tau"] == 150.0
    assert "150 us" in data.description and not list(cache_dir.glob("*"))


def test_laser_data_sets_differ_by_delay():
    sets = load_laser_all(n_samples=3000, cache=False)
    assert sorted(sets) == [50, 150, 400]
    assert not np.allclose(sets[50].series, sets[400].series)


def test_corrupt_cache_file_is_regenerated(cache_dir):
    good = load_laser(400, n_samples=2000)
    path = next(cache_dir.glob("*.npy"))
    path.write_bytes(b"garbage")
    np.testing.assert_array_equal(load_laser(400, n_samples=2000).series, good.series)


def test_bad_arguments(cache_dir, monkeypatch):
    with pytest.raises(ValueError, match=r"one of \(50, 150, 400\)"):
        load_laser(100)
    with pytest.raises(ValueError, match=">= 1000"):
        load_laser(50, n_samples=10)
    monkeypatch.setenv("SKDELAY_DATA", os.path.join(os.path.dirname(datasets.__file__), "data"))
    with pytest.raises(ValueError, match="inside the skdelay package"):
        data_home()
