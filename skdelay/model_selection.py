"""Choosing the delay models' settings from the data (public namespace).

* :func:`select_model_options` -- neighbourhood size and ridge of the local
  linear delay models by time-series cross-validation of one-step and
  iterated forecasts (scikit-learn ``GridSearchCV`` + ``TimeSeriesSplit``);
* :class:`ModelOptions` -- the settings it returns, accepted by
  :func:`skdelay.dynamics.minimal_embedding` and :func:`skdelay.analyze_series`;
* :func:`sampling_step` -- the coarser step an oversampled record needs;
* :func:`select_spectrum_model` -- model step, window span, neighbours and
  ridge of the model behind a Lyapunov spectrum, by time-series
  cross-validation of free runs (:func:`spectrum_of_selection` fits it and
  returns its spectrum; :func:`dominant_period` sets the span grid);
  :func:`select_spectrum_model_staged` makes the same choice in two cheaper
  stages (time scale, then neighbours and ridge).
"""

from __future__ import annotations

from ._model import ModelOptions
from ._model_selection import (
    ModelSelection,
    SpectrumModelSelection,
    dominant_period,
    select_model_options,
    select_spectrum_model,
    select_spectrum_model_staged,
    spectrum_of_selection,
)
from ._sampling import sampling_step

__all__ = ["ModelOptions", "ModelSelection", "SpectrumModelSelection", "dominant_period",
           "sampling_step", "select_model_options", "select_spectrum_model",
           "select_spectrum_model_staged", "spectrum_of_selection"]
