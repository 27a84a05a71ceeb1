"""The paper's Takens cross-check: model-free estimates beside the delay model's.

Bünner et al. check the low-dimensional case (delay 50 us) with a standard
delay embedding (their Sec. III): the correlation dimension of the Poincaré
section of maxima after local projective noise reduction, and Kantz's
maximal exponent from the divergence of neighbouring segments.  Both are
fuzzy on noisy hyperchaotic flow data (the paper: "we cannot draw a definite
conclusion"), so :func:`takens_cross_check` reports them as *ranges* over
several embeddings and says whether the model's values are consistent with
them; it never replaces the model's numbers.

Every setting is read off the data or the estimated delay: the lag is the
first minimum of the mutual information, the embedding windows span one to
two delays (a delay system's state is a window of at least one delay), the
Theiler window is two delays.  Only the number of noise-reduction iterations
(10) is the paper's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

from ._checks import check_positive_int, check_series
from .classic import (
    correlation_dimension,
    maximal_lyapunov_exponent,
    noise_reduction,
    poincare_section,
)
from .validation import mutual_information

__all__ = ["TakensCheck", "takens_cross_check"]

#: noise-reduction iterations on the Poincaré section (the paper: "10 iterations, which
#: turned out to be sufficient")
NR_ITERATIONS = 10
#: embedding windows, in delays, for Kantz's exponent: one delay is the least a delay
#: system's state needs; the spread over 1-2 delays shows how much the estimate depends
#: on the embedding
WINDOWS = (1.0, 1.5, 2.0)
#: extrema less prominent than this fraction of the series' standard deviation are
#: noise wiggles (the laser data carry 0.5 % measurement noise and 12-bit steps)
PROMINENCE = 0.05
#: largest lag of the mutual information searched for its first minimum, in delays
MI_LAGS = 1.0
#: relative difference within which D2 + 1 of the section and the model's D_KY "agree":
#: the paper calls its D2 "too fuzzy to derive a well defined dimension"; 30 % is the
#: tolerance the project's reproduction issue allows between D_KY values themselves
DIM_AGREEMENT = 0.3


@dataclass(frozen=True)
class TakensCheck:
    """Model-free estimates from a standard delay embedding.

    Attributes
    ----------
    lag : int
        Embedding lag (samples): first minimum of the mutual information.
    kantz : pandas.DataFrame
        Index ``dim`` (embedding dimension); columns ``window`` (samples),
        ``exponent`` (per time unit) and ``fit_start``/``fit_stop`` (time units).
    n_section : int
        Points of the Poincaré section of maxima.
    d2_raw, d2_reduced : float
        Correlation dimension of the section before and after noise
        reduction; the flow's dimension is one more.  NaN when the section is
        too short to show a scaling range.
    d2_raw_spread, d2_reduced_spread : float
        Spread of the local slopes in the scaling range (small = clear plateau).
    """

    lag: int
    kantz: pd.DataFrame
    n_section: int
    d2_raw: float
    d2_raw_spread: float
    d2_reduced: float
    d2_reduced_spread: float

    @property
    def lambda_range(self):
        """(smallest, largest) of Kantz's exponents over the embeddings."""
        lam = self.kantz["exponent"].to_numpy()
        return float(np.nanmin(lam)), float(np.nanmax(lam))

    def table(self, model, exact=None, scale=1.0):
        """Model-free values beside the model's (and the exact ones): a small DataFrame.

        ``model`` and ``exact`` are dicts with ``lambda_max`` and ``D_KY`` (per
        time unit); ``scale`` converts exponents to the reported unit.
        """
        lo, hi = self.lambda_range
        rows = {
            "lambda_max": {
                "standard embedding (Kantz)": f"{lo * scale:.3g} .. {hi * scale:.3g}",
                "this model": f"{model['lambda_max'] * scale:.3g}"},
            "D_KY (flow) / D2 + 1 (section)": {
                "standard embedding (Kantz)": (
                    f"{self.d2_reduced + 1:.3g} (noise-reduced section; raw "
                    f"{self.d2_raw + 1:.3g})"),
                "this model": f"{model['D_KY']:.3g}"},
        }
        if exact is not None:
            rows["lambda_max"]["exact (simulator)"] = f"{exact['lambda_max'] * scale:.3g}"
            rows["D_KY (flow) / D2 + 1 (section)"]["exact (simulator)"] = (
                f"{exact['D_KY']:.3g}")
        return pd.DataFrame.from_dict(rows, orient="index")

    def sentence(self, model, scale=1.0, unit="1/time unit"):
        """One sentence on consistency, conditioned on the numbers."""
        lo, hi = self.lambda_range
        lam = model["lambda_max"]
        # Kantz's slope is itself uncertain by the spread over embeddings: a model value
        # within the range widened by half its width counts as consistent
        half = 0.5 * (hi - lo)
        if lo - half <= lam <= hi + half:
            lam_text = (f"the model's largest exponent {lam * scale:.3g} {unit} is consistent "
                        f"with Kantz's estimates ({lo * scale:.3g} to {hi * scale:.3g} {unit} "
                        f"over {len(self.kantz)} embeddings)")
        else:
            side = "above" if lam > hi else "below"
            lam_text = (f"the model's largest exponent {lam * scale:.3g} {unit} lies {side} "
                        f"Kantz's estimates ({lo * scale:.3g} to {hi * scale:.3g} {unit} "
                        f"over {len(self.kantz)} embeddings)")
        d2 = self.d2_reduced + 1.0
        ratio = d2 / model["D_KY"] if model["D_KY"] > 0 else math.inf
        if not np.isfinite(d2):
            dim_text = (f"the Poincaré section ({self.n_section} points) is too short for a "
                        "correlation dimension")
        elif abs(ratio - 1.0) <= DIM_AGREEMENT:
            dim_text = (f"the noise-reduced Poincaré section gives D2 + 1 = {d2:.3g}, close to "
                        f"the model's D_KY {model['D_KY']:.3g}")
        else:
            dim_text = (f"the noise-reduced Poincaré section gives D2 + 1 = {d2:.3g}, "
                        f"{'below' if ratio < 1 else 'above'} the model's D_KY "
                        f"{model['D_KY']:.3g} (a correlation dimension from "
                        f"{self.n_section} section points cannot resolve more than about "
                        f"{2 * math.log10(max(self.n_section, 10)):.0f} dimensions)")
        return f"Standard delay embedding: {lam_text}; {dim_text}."


def _first_minimum(curve):
    """Index of the first local minimum of ``curve`` (its global minimum if none)."""
    rising = np.flatnonzero(np.diff(curve) > 0)
    return int(rising[0]) if rising.size else int(np.argmin(curve))


def takens_cross_check(series, delay, *, sample_dt=1.0, n_reference=2000, random_state=None):
    """Correlation dimension and maximal exponent from a standard delay embedding.

    Parameters
    ----------
    series : array-like of shape (n_samples,)
        Sampled flow (the laser intensity).
    delay : float
        Estimated feedback delay in samples (sets the embedding windows and
        the Theiler window).
    sample_dt : float, default=1.0
        Sampling step; exponents are returned per time unit.
    n_reference : int, default=2000
        Reference points of the correlation sums and of Kantz's divergence.
    random_state : int, RandomState or None

    Returns
    -------
    TakensCheck

    Examples
    --------
    >>> from skdelay.datasets import load_laser
    >>> from skdelay._crosscheck import takens_cross_check
    >>> data = load_laser(50, n_samples=20_000, cache=False)
    >>> check = takens_cross_check(data.series, 50, random_state=0)
    >>> check.lag > 0 and check.n_section > 100
    True
    """
    s = check_series(series, min_length=200)
    if not (np.isfinite(delay) and delay >= 2):
        raise ValueError(f"delay must be at least 2 samples, got {delay!r}; pass the "
                         "estimated delay of the series.")
    n_reference = check_positive_int(n_reference, name="n_reference", minimum=100)
    delay = float(delay)
    mi = mutual_information(s, max(2, int(MI_LAGS * delay)))
    lag = max(1, _first_minimum(mi))
    theiler = int(2 * delay)
    max_steps = int(4 * delay)
    n_ref = min(n_reference, s.size // 4)
    rows = {}
    for window in WINDOWS:
        dim = max(2, math.ceil(window * delay / lag))
        # half the record must remain for reference segments after window and divergence
        if (dim - 1) * lag + max_steps + theiler >= s.size // 2:
            continue
        res = maximal_lyapunov_exponent(
            s, dim=dim, lag=lag, theiler_window=theiler, sample_dt=sample_dt,
            max_steps=max_steps, n_reference=n_ref, random_state=random_state)
        rows[dim] = {"window": (dim - 1) * lag + 1, "exponent": res.exponent,
                     "fit_start": res.fit_range[0], "fit_stop": res.fit_range[1]}
    if not rows:
        raise ValueError(f"the series ({s.size} samples) is too short for a standard "
                         f"embedding spanning the delay {delay:g}; use a longer record.")
    kantz = pd.DataFrame.from_dict(rows, orient="index")
    kantz.index.name = "dim"
    _, section = poincare_section(s, kind="maxima", prominence=PROMINENCE * float(np.std(s)))
    reduced = noise_reduction(section, iterations=NR_ITERATIONS)
    d2 = {}
    for name, values in (("raw", section), ("reduced", reduced)):
        try:
            res = correlation_dimension(values, dims=range(1, 11), theiler_window=2,
                                        n_reference=min(n_reference, values.size),
                                        random_state=random_state)
        except ValueError:  # no scaling range: too few section points (said in the text)
            d2[name] = (math.nan, math.nan)
        else:
            d2[name] = (float(res.dimension), float(res.spread))
    return TakensCheck(lag=lag, kantz=kantz, n_section=int(section.size),
                       d2_raw=d2["raw"][0], d2_raw_spread=d2["raw"][1],
                       d2_reduced=d2["reduced"][0], d2_reduced_spread=d2["reduced"][1])
