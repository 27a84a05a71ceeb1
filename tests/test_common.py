"""scikit-learn API compliance of the core estimators (no expected failures).

Some checks feed two-column data, so the instances use grids that need at most
two lag columns.
"""

from sklearn.utils.estimator_checks import parametrize_with_checks

from skdelay._embedding import TwoWindowEmbedding
from skdelay._local_linear import LocalLinearDelayMap
from skdelay._selection import DelaySelectorCV


@parametrize_with_checks([
    TwoWindowEmbedding(),
    TwoWindowEmbedding(m=1, tau=2),
    LocalLinearDelayMap(),
    LocalLinearDelayMap(n_neighbors=5, radius=0.5, order=0),
    DelaySelectorCV(),
    DelaySelectorCV(m=(1, 2), tau=1),
    DelaySelectorCV(m=1, tau=(1, 2), cv=2),
])
def test_sklearn_compatible(estimator, check):
    check(estimator)
