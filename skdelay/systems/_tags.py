"""Type tags of the registered systems (namedtuple classes made on demand).

The numba kernels are specialised -- and cached on disk -- per tag type.  A
tag class is named ``<System>_<dim>d_<hash of the source of rhs and jac>``:
editing a system's equations changes its tag and invalidates the cached
kernels (numba's cache alone only watches the kernel's own file), and the
kernels read the state dimension at compile time, as the class attribute
``DIM``, to size their work arrays on the stack
(:func:`skdelay._jit.stack_array`).  Classes
are created on attribute access (PEP 562 ``__getattr__``), so unpickling a
stale cache index that names an old tag never fails.
"""

from __future__ import annotations

import re
from collections import namedtuple

_CLASSES = {}
_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*_[0-9a-f]{12}$")
_DIM = re.compile(r"_([0-9]+)d_[0-9a-f]{12}$")


def tag_class(name):
    """The tag class called ``name`` (created once)."""
    cls = _CLASSES.get(name)
    if cls is None:
        cls = namedtuple(name, ["dim"], module=__name__)
        dim = _DIM.search(name)
        cls.DIM = int(dim.group(1)) if dim else None  # None: a name from an older version
        _CLASSES[name] = cls
    return cls


def __getattr__(name):
    if not _NAME.match(name):
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return tag_class(name)
