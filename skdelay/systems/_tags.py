"""Type tags of the registered systems (namedtuple classes made on demand).

The numba kernels are specialised -- and cached on disk -- per tag type.  A
tag class is named ``<System>_<hash of the source of rhs and jac>`` so that
editing a system's equations changes its tag and invalidates the cached
kernels (numba's cache alone only watches the kernel's own file).  Classes
are created on attribute access (PEP 562 ``__getattr__``), so unpickling a
stale cache index that names an old tag never fails.
"""

from __future__ import annotations

from collections import namedtuple

_CLASSES = {}


def tag_class(name):
    """The tag class called ``name`` (created once)."""
    cls = _CLASSES.get(name)
    if cls is None:
        cls = namedtuple(name, ["dim"], module=__name__)
        _CLASSES[name] = cls
    return cls


def __getattr__(name):
    if name.startswith("__"):
        raise AttributeError(name)
    return tag_class(name)
