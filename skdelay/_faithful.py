"""Minimal faithful window length ``m_d``: which models reproduce the data globally.

For every ``m`` a two-window model is fitted, iterated from on-attractor
initial conditions and its run compared with the data (Buenner et al. sec. IV):
boundedness, histogram, power spectrum, cross-prediction error and the
convergence of the Lyapunov spectrum with ``m``.  Each distance is judged
against the same statistic between two stretches of the data of the run's
length ("data-vs-data", the sampling spread of a perfect model).
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from sklearn.pipeline import make_pipeline

from ._checks import check_positive_int, check_random_state, check_series
from ._embedding import TwoWindowEmbedding, required_lags
from ._local_linear import LocalLinearDelayMap
from ._windows import lagged_windows

#: Documented faithfulness thresholds (see :func:`minimal_embedding`).
THRESHOLDS = {
    "histogram": 2.0,   # d_hist(data, run) <= 2 x d_hist(data_a, data_b)
    "spectrum": 2.0,    # d_psd(data, run)  <= 2 x d_psd(data_a, data_b)
    "chi": 1.25,        # chi(data, run)    <= 1.25 x chi(data, data)
    "lyapunov": 0.25,   # relative change of lambda_1 and D_KY vs the m_max model <= 25 %
}


def _default_taus(series, m_values, tau_grid, random_state, n_jobs):
    from ._selection import forecast_error_curve

    curve = forecast_error_curve(series, m=tuple(m_values), tau=tau_grid,
                                 n_queries=min(series.size // 2, 5000),
                                 random_state=random_state, n_jobs=n_jobs)
    return {m: int(curve[m].idxmin()) for m in m_values}


def _compare(s, run, chi_m, chi_tau, sample_dt, seed):
    """Distances data-vs-run and data-vs-data, all between stretches of the run's length.

    ``a`` = first ``L`` samples of the data, ``b`` = last ``L`` (disjoint),
    ``L = min(len(run), len(data) // 2)``: the ``*_ref`` values are what a
    perfect model would score with this much data.  Power spectra are
    compared below the frequency holding 99 % of the data's power, so the
    measurement-noise floor of the data (absent from a model run) does not count.
    """
    from . import validation

    n = min(run.size, s.size // 2)
    a, b, run = s[:n], s[s.size - n:], run[:n]
    freqs, psd = validation.power_spectrum(a, sample_dt=sample_dt)
    cum = np.cumsum(psd) / psd.sum()
    f_max = float(freqs[min(np.searchsorted(cum, 0.99) + 1, freqs.size - 1)])
    chi = {"m": chi_m, "tau": chi_tau, "random_state": seed, "n_queries": min(n, 5000)}
    return {
        "hist_distance": validation.histogram_distance(a, run).distance,
        "hist_ref": validation.histogram_distance(a, b).distance,
        "spectrum_distance": validation.spectrum_distance(
            a, run, sample_dt=sample_dt, max_frequency=f_max).distance,
        "spectrum_ref": validation.spectrum_distance(
            a, b, sample_dt=sample_dt, max_frequency=f_max).distance,
        "chi": validation.cross_prediction_error(a, run, **chi),
        "chi_ref": validation.cross_prediction_error(a, b, **chi),
    }


def _fit(series, m, tau, n_neighbors, ridge, theiler_window):
    X, y = lagged_windows(series, required_lags(m, tau))
    model = make_pipeline(
        TwoWindowEmbedding(m=m, tau=tau),
        LocalLinearDelayMap(n_neighbors=n_neighbors, ridge=ridge, theiler_window=theiler_window),
    )
    return model.fit(X, y)


def minimal_embedding(series, *, tau=None, tau_grid=range(1, 101), m_max=5, m_min=1,
                      n_steps=None, n_neighbors=None, ridge=1e-3, theiler_window=2,
                      n_transient=None, n_exponents=None, chi_m=None, sample_dt=1.0,
                      thresholds=None, random_state=None, n_jobs=None):
    """Smallest window length ``m`` whose iterated model reproduces the data.

    For ``m = m_min .. m_max``: fit ``Pipeline(TwoWindowEmbedding(m, tau_m),
    LocalLinearDelayMap)`` on ``series``, iterate it for ``n_steps`` from a
    random on-attractor history (a segment of the data), drop ``n_transient``
    steps, and compare the run with a stretch ``a`` of the data of the same
    length ``L = min(n_steps, len(series) // 2)``.  Every distance has a
    reference: the same statistic between ``a`` and a disjoint stretch ``b``
    of the data (the ``*_ref`` columns: what a perfect model scores with this
    much data).  A model is **faithful** when all of these hold:

    * *bounded*: the run never leaves the data's support (see :func:`iterate`);
    * ``hist_distance <= 2 * hist_ref``: Hellinger distance of the value
      histograms (:func:`~skdelay.validation.histogram_distance`);
    * ``spectrum_distance <= 2 * spectrum_ref``: rms log-PSD distance
      (:func:`~skdelay.validation.spectrum_distance`) below the frequency that
      holds 99 % of the data's power (the data's measurement-noise floor is not
      a model property);
    * ``chi <= 1.25 * chi_ref``: cross-prediction error chi(a, run) of the data
      from the run's vectors vs chi(a, b), local constant, in ``chi_m + chi_m``
      dimensions at ``tau_{chi_m}`` (the paper's table);
    * ``lyap_change <= 0.25``: the Lyapunov spectrum has converged, i.e. the
      larger of the relative changes of ``lambda_1`` and of ``D_KY`` against
      the model with ``m_max`` is at most 25 %.

    The factors are :data:`THRESHOLDS`; override them with ``thresholds``
    (keys ``histogram``, ``spectrum``, ``chi``, ``lyapunov``).  One run per
    ``m`` is compared, so borderline cases can flip with ``random_state``;
    longer runs (``n_steps``) sharpen the decision.

    Parameters
    ----------
    series : array-like of shape (n_samples,)
        The data, sampled at step 1 (``sample_dt`` only sets units).
    tau : int or dict {m: int}, default=None
        Delay in samples for all ``m`` or per ``m``; default: the minimum of
        each ``m``'s forecast-error curve (:func:`~skdelay.forecast_error_curve`,
        the scan behind :class:`~skdelay.DelaySelectorCV`) over ``tau_grid``.
    tau_grid : iterable of int, default=range(1, 101)
        Delays scanned when ``tau`` is None (must cover the feedback delay).
    m_max, m_min : int, default=5, 1
        Window lengths to test.
    n_steps : int, default=None
        Length of each model run (default: ``min(len(series), 50_000)``).
    n_neighbors : int, default=None
        Neighbourhood size of the models (default ``4 * (2 m + 1)``).
    ridge, theiler_window
        Passed to :class:`~skdelay.LocalLinearDelayMap`.
    n_transient : int, default=None
        Initial run steps dropped (default ``max(2 * tau, 500)``).
    n_exponents : int, default=None
        Exponents computed per model (default ``min(D, 30)``).
    chi_m : int, default=None
        Window length of the cross-prediction vectors (default ``m_max``).
    sample_dt : float, default=1.0
        Time per sample (for the power spectra and exponents).
    thresholds : dict, default=None
        Overrides of :data:`THRESHOLDS`.
    random_state : int, Generator or None
        Initial conditions and probes.
    n_jobs : int, default=None
        Passed to the delay scan.

    Returns
    -------
    table : pandas.DataFrame
        One row per ``m`` (index ``m``): ``tau``, ``bounded``,
        ``hist_distance``, ``hist_ref``, ``spectrum_distance``,
        ``spectrum_ref``, ``chi``, ``chi_ref``, ``lambda_1``, ``d_ky``,
        ``h_ks``, ``n_positive``, ``lyap_change``, ``faithful``.
    m_d : int or None
        The smallest faithful ``m`` (None if none is).

    Examples
    --------
    >>> from skdelay.dynamics import minimal_embedding
    >>> from skdelay.systems import MackeyGlass
    >>> x = MackeyGlass(tau=17.0).simulate(20000, random_state=0)
    >>> table, m_d = minimal_embedding(x, tau=17, m_max=3, n_steps=8000, random_state=0)
    >>> list(table.index), m_d in (1, 2, 3)
    ([1, 2, 3], True)
    """
    from .dynamics import iterate, lyapunov_spectrum

    s = check_series(series, name="series", min_length=100)
    m_max = check_positive_int(m_max, name="m_max")
    m_min = check_positive_int(m_min, name="m_min", maximum=m_max)
    m_values = list(range(m_min, m_max + 1))
    rng = check_random_state(random_state)
    unknown = set(thresholds or {}) - set(THRESHOLDS)
    if unknown:
        raise ValueError(f"unknown threshold(s) {sorted(unknown)}; valid keys: "
                         f"{sorted(THRESHOLDS)}.")
    th = dict(THRESHOLDS, **(thresholds or {}))
    if tau is None:
        taus = _default_taus(s, m_values, tau_grid, int(rng.randint(2**31)), n_jobs)
    elif isinstance(tau, dict):
        missing = [m for m in m_values if m not in tau]
        if missing:
            raise ValueError(f"tau dict has no delay for m = {missing}; give one per m.")
        taus = {m: check_positive_int(tau[m], name=f"tau[{m}]") for m in m_values}
    else:
        taus = dict.fromkeys(m_values, check_positive_int(tau, name="tau"))
    n_steps = min(s.size, 50_000) if n_steps is None else check_positive_int(n_steps,
                                                                              name="n_steps")
    chi_m = m_max if chi_m is None else check_positive_int(chi_m, name="chi_m")
    chi_tau = taus[m_max]
    for m in m_values:
        dim = required_lags(m, taus[m])
        need = dim + 1 + max(20 * (2 * m + 1), 2 * dim, 40)
        if s.size < need:
            raise ValueError(f"series has {s.size} samples; m={m}, tau={taus[m]} needs at least "
                             f"{need}. Pass a longer series or smaller m_max / tau.")

    rows, spectra = {}, {}
    for m in m_values:
        t_m = taus[m]
        dim = required_lags(m, t_m)
        k = 4 * (2 * m + 1) if n_neighbors is None else n_neighbors
        model = _fit(s, m, t_m, k, ridge, theiler_window)
        skip = max(2 * t_m, 500) if n_transient is None else int(n_transient)
        start = int(rng.randint(0, s.size - dim))
        run = iterate(model, s[start:start + dim], n_steps + skip, on_escape="ignore")
        run = np.asarray(run[skip:])
        bounded = run.size == n_steps and np.ptp(run) > 0
        row = {"tau": t_m, "bounded": bool(bounded)}
        if bounded:
            row.update(_compare(s, run, chi_m, chi_tau, sample_dt, int(rng.randint(2**31))))
        n_exp = min(dim, 30) if n_exponents is None else min(dim, int(n_exponents))
        spec = lyapunov_spectrum(model, s, n_exponents=n_exp, sample_dt=sample_dt)
        spectra[m] = spec
        row.update(lambda_1=spec.exponents[0], d_ky=spec.kaplan_yorke_dimension,
                   h_ks=spec.ks_entropy, n_positive=spec.n_positive)
        rows[m] = row

    table = pd.DataFrame.from_dict(rows, orient="index")
    table.index.name = "m"
    ref = table.loc[m_max]
    table["lyap_change"] = np.maximum(
        np.abs(table["lambda_1"] - ref["lambda_1"]) / abs(ref["lambda_1"]),
        np.abs(table["d_ky"] - ref["d_ky"]) / max(ref["d_ky"], 1.0))
    for col in ("hist_distance", "hist_ref", "spectrum_distance", "spectrum_ref", "chi",
                "chi_ref"):
        if col not in table:
            table[col] = np.nan
    table["faithful"] = (
        table["bounded"]
        & (table["hist_distance"] <= th["histogram"] * table["hist_ref"])
        & (table["spectrum_distance"] <= th["spectrum"] * table["spectrum_ref"])
        & (table["chi"] <= th["chi"] * table["chi_ref"])
        & (table["lyap_change"] <= th["lyapunov"])
    ).fillna(False).astype(bool)
    faithful = table.index[table["faithful"]]
    return table, (int(faithful[0]) if len(faithful) else None)
