"""Choosing the delay models' settings from the data (public namespace).

* :func:`select_model_options` -- neighbourhood size and ridge of the local
  linear delay models by time-series cross-validation of one-step and
  iterated forecasts (scikit-learn ``GridSearchCV`` + ``TimeSeriesSplit``);
* :class:`ModelOptions` -- the settings it returns, accepted by
  :func:`skdelay.dynamics.minimal_embedding` and :func:`skdelay.analyze_series`;
* :func:`sampling_step` -- the coarser step an oversampled record needs.
"""

from __future__ import annotations

from ._model import ModelOptions
from ._model_selection import ModelSelection, select_model_options
from ._sampling import sampling_step

__all__ = ["ModelOptions", "ModelSelection", "sampling_step", "select_model_options"]
