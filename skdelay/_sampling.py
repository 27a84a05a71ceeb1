"""Is the record oversampled?  Measurement noise against the one-step increment.

When a smooth signal is sampled much faster than it changes, the one-step
increment ``s[t+1] - s[t]`` is buried in measurement noise: every forecast is
"the last value", the delayed window cannot improve it, and the
forecast-error curve is flat at the noise floor (no dip, whatever the delay).
Taking every ``h``-th sample lets the increment grow (about linearly in ``h``)
while the noise stays, so the delay becomes visible again.

:func:`noise_and_increments` separates the two from the structure function
``D(k) = var(s[t+k] - s[t])``: for a smooth signal plus white measurement
noise of standard deviation ``e``, ``D(k) = 2 e^2 + c k^2 + O(k^4)`` at small
``k``, so a least-squares fit of ``D`` against ``k^2`` over the first lags gives
``2 e^2`` as its intercept.

What the delayed window can add to a forecast is the part of the next value
that the first window cannot extrapolate: for a record in its Taylor regime
that is the *second* difference ``s[t+h] - 2 s[t] + s[t-h]`` (the first
window already extrapolates the increment linearly), which grows like ``h^2``.
A delay equation whose right-hand side depends only on the delayed value,
sampled 50 times per delay, has one-step increments 12 times its 0.5 % noise
and yet no dip at step 1 (its second difference is 0.2 times the noise).
:func:`sampling_step` returns 1 unless the record is in its Taylor regime
(the structure function's noise floor equals the white-noise level of
:func:`white_noise_level`), and otherwise the smallest ``h`` whose signal
second difference exceeds :data:`INCREMENT_TO_NOISE` times the noise.
"""

from __future__ import annotations

import math

import numpy as np

from ._checks import check_series
from ._neighbours import Standardiser

__all__ = ["INCREMENT_TO_NOISE", "MAX_STEP", "SMOOTH_RATIO", "noise_and_increments",
           "sampling_step", "smooth_at_step", "white_noise_level"]

#: The signal part of the second difference at the chosen step must exceed the noise this
#: many times.  A dip is a dip when it is at least 10 % deep
#: (:data:`skdelay._dips.MIN_RELATIVE_DEPTH`); at the dip the error is the noise carried
#: through the local map, off it the noise plus the part of the next value the first window
#: cannot extrapolate (at most the second difference), of which the delayed window explains
#: a fraction -- twice the noise leaves room for that.
INCREMENT_TO_NOISE = 2.0
#: The record is in its Taylor regime (smooth at the sampling step, so oversampled) when
#: the structure function's noise floor and the high-order-difference white-noise level
#: (two estimates of the same noise that agree only for a smooth signal) lie within this
#: fraction of each other.  Mackey-Glass sampled at 1 per time unit is not smooth at its
#: step: the two differ by a factor 8 (0.5 % noise) and 1.3 (5 % noise); sampled 20 times
#: faster, or a delay equation at 50 samples per delay, they agree within 5 %.
NOISE_AGREEMENT = 0.2
#: Largest step considered (the delay must still span several coarse samples).
MAX_STEP = 64
#: A record is smooth at its sampling step when, with the white-noise level of
#: :func:`white_noise_level` taken off, its second difference is below this fraction of
#: its first (a smooth signal sampled ``n`` times per radian: about ``1 / n``; a rough one
#: about 1, white noise sqrt(3)).  Measured (3e4 samples, 0.5 and 5 % noise): Ikeda at
#: steps 0.01 / 0.25 / 0.5 / 1: 0.15-0.40 / 1.05 / 1.10 / 1.18; the electro-optic
#: oscillator at 0.05 / 0.25 / 0.5: 0.17-0.26 / 0.72 / 1.01; Mackey-Glass tau = 17 at 1 and
#: tau = 100 at 2: 0.22-0.24 and 0.42-0.43; the laser at 1 us 0.75.  The high-order
#: differences alone cannot tell: Ikeda's at step 0.25-1 level off too ("resolved"), at a
#: "noise" of 0.36-0.72 standard deviations that is its own fast chaos.
SMOOTH_RATIO = 0.5
#: Lags of the structure function fitted for the intercept (quadratic regime).
_FIT_LAGS = 4
#: Largest misfit of ``D(k) = 2 e^2 + c k^2`` over those lags, relative to ``D(4)``: a
#: smooth signal with white noise fits to rounding (< 1 %); a chaotic map's structure
#: function saturates after one step and misses by tens of per cent.
QUADRATIC_MISFIT = 0.05
#: Highest order of the differences in :func:`white_noise_level`.  White noise of standard
#: deviation ``e`` contributes ``C(2p, p) e^2`` to ``var(diff(s, p))`` while a smooth
#: signal's share falls like ``(2 pi f)^(2p)``: on Mackey-Glass (tau = 17 and 30, 3e4
#: samples) with 0.5, 1 and 5 % noise the estimate of orders 4..8 is within 2 % of the
#: true level; on clean Mackey-Glass it is 1e-4 at order 6 and below at 8.
MAX_DIFFERENCE_ORDER = 8
#: The noise floor is *resolved* when the estimates of the last three orders lie within
#: this fraction of the smallest one (Mackey-Glass with 0.5-5 % noise: < 1 %); data that
#: are not smooth at their sampling step keep falling (the simulated laser at 1 us: 20-40 %
#: from order 6 to 8) or, for a map, grow with the order (Henon: 1.14 at order 1, 1.46 at
#: 8), so the estimate is only an upper bound there.
PLATEAU = 0.05


def noise_and_increments(series, max_step=MAX_STEP):
    """Noise level and signal increment per step, from the structure function.

    Returns ``(noise, steps, increments)``: the measurement-noise standard
    deviation (0 when the record is not smooth at its sampling scale, so no
    noise floor can be separated), the steps ``1..max_step`` and the standard
    deviation of the *signal* part of ``s[t+h] - s[t]`` for each (noise removed).

    Examples
    --------
    >>> import numpy as np
    >>> from skdelay._sampling import noise_and_increments
    >>> t = np.arange(50_000) * 0.01
    >>> x = np.sin(t) + 0.01 * np.random.default_rng(0).standard_normal(t.size)
    >>> noise, steps, inc = noise_and_increments(x, max_step=8)
    >>> round(noise, 3), bool(inc[0] < noise < inc[7])
    (0.01, True)
    """
    raw = check_series(series, name="series", min_length=8 * max_step)
    scale = Standardiser.fit(raw).scale  # exact power of two: no under- or overflow below
    s = raw / scale
    steps = np.arange(1, max_step + 1)
    d = np.array([np.var(s[h:] - s[:-h]) for h in steps])
    k2 = steps[:_FIT_LAGS].astype(float) ** 2
    slope, intercept = np.polyfit(k2, d[:_FIT_LAGS], 1)
    misfit = np.max(np.abs(d[:_FIT_LAGS] - (intercept + slope * k2))) / d[_FIT_LAGS - 1]
    if slope <= 0 or intercept <= 0 or misfit > QUADRATIC_MISFIT:
        # not smooth at the sampling scale (a map, or a flow sampled coarsely): the
        # structure function is not quadratic, so no noise floor can be read off it
        intercept = 0.0
    noise = math.sqrt(intercept / 2.0)
    increments = np.sqrt(np.maximum(d - 2 * noise ** 2, 0.0))
    return noise * scale, steps, increments * scale


def sampling_step(series, *, max_step=MAX_STEP):
    """Smallest step ``h`` at which the second difference clearly exceeds the noise.

    1 for records that are not oversampled (not in their Taylor regime at the
    sampling step, or without a resolvable noise floor).

    Examples
    --------
    >>> import numpy as np
    >>> from skdelay._sampling import sampling_step
    >>> t = np.arange(100_000) * 0.02
    >>> rng = np.random.default_rng(1)
    >>> # second difference 4e-4 h^2 of the sine (amplitude 1) against 2 x 0.01 of noise
    >>> sampling_step(np.sin(t) + 0.01 * rng.standard_normal(t.size))
    9
    >>> sampling_step(np.sin(5 * t) + 0.01 * rng.standard_normal(t.size))
    1
    """
    s = check_series(series, name="series")
    max_step = int(min(max_step, s.size // 64))
    if max_step < 2:
        return 1
    noise, steps, _ = noise_and_increments(s, max_step=max_step)
    if noise == 0:
        return 1
    white, resolved = white_noise_level(s)
    if not resolved or abs(noise - white) > NOISE_AGREEMENT * max(noise, white):
        return 1  # not smooth at the sampling step: the record is not oversampled
    scale = Standardiser.fit(s).scale
    u, e = s / scale, noise / scale
    for h in steps:
        second = u[2 * h:] - 2.0 * u[h:-h] + u[:-2 * h]
        if math.sqrt(max(float(np.var(second)) - 6.0 * e * e, 0.0)) >= INCREMENT_TO_NOISE * e:
            return int(h)
    return int(max_step)


def white_noise_level(series, *, max_order=MAX_DIFFERENCE_ORDER):
    """Upper estimate of white measurement noise from high-order differences.

    ``e_p = sqrt(var(diff(s, p)) / C(2p, p))`` is an upper estimate of the
    noise's standard deviation for every ``p`` (the signal adds to the
    variance); returns ``(min_p e_p, resolved)``, ``resolved`` when the
    estimates level off over the last orders (:data:`PLATEAU`: the noise floor
    is reached, so the value is the noise level itself, not only a bound).

    Examples
    --------
    >>> import numpy as np
    >>> from skdelay._sampling import white_noise_level
    >>> t = np.arange(50_000) * 0.05
    >>> x = np.sin(t) + 0.01 * np.random.default_rng(0).standard_normal(t.size)
    >>> noise, resolved = white_noise_level(x)
    >>> round(noise, 3), resolved
    (0.01, True)
    """
    raw = check_series(series, name="series", min_length=16 * max_order)
    scale = Standardiser.fit(raw).scale
    s = raw / scale
    est = np.array([math.sqrt(np.var(np.diff(s, p)) / math.comb(2 * p, p))
                    for p in range(1, max_order + 1)])
    noise = float(est.min())
    # levelled off at the smallest value (a map's estimates grow with the order instead)
    resolved = bool(noise > 0 and est[-3:].max() <= (1.0 + PLATEAU) * noise)
    return noise * scale, resolved


def smooth_at_step(series):
    """Whether the record is smooth at its sampling step (:data:`SMOOTH_RATIO`).

    Smooth records only gain from coarser steps what their noise hid; rough ones (maps,
    coarsely sampled flows) lose the delay's resolution.

    Examples
    --------
    >>> import numpy as np
    >>> from skdelay._sampling import smooth_at_step
    >>> rng = np.random.default_rng(0)
    >>> t = np.arange(20_000) * 0.05
    >>> smooth_at_step(np.sin(t) + 0.01 * rng.standard_normal(t.size))
    True
    >>> smooth_at_step(rng.standard_normal(20_000))
    False
    """
    s = check_series(series, name="series", min_length=16 * MAX_DIFFERENCE_ORDER)
    u = s / Standardiser.fit(s).scale
    noise, resolved = white_noise_level(u)
    if not resolved:
        return False
    first = float(np.var(np.diff(u))) - 2.0 * noise ** 2
    second = float(np.var(np.diff(u, 2))) - 6.0 * noise ** 2
    return bool(first > 0 and max(second, 0.0) < SMOOTH_RATIO ** 2 * first)
