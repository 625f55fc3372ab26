# SPDX-License-Identifier: BSD-3-Clause
"""mypy's stubgen, run on the built extension with one addition to its docstring parser:
the bare ``*`` that pybind11 writes before keyword-only arguments (py::kw_only()).

stubgen reads a C extension's signatures from the first line of each docstring, and the
parser of mypy 1.0 (Debian's) takes ``*`` for a malformed argument name: it then drops the
whole signature and writes ``(*args, **kwargs)``, so the stubs lose every parameter of a
constructor such as ``SACMultiPlaneSegmentation(*, distance_threshold_m: float = 0.05,
...)``. Accepting ``*`` as an argument makes stubgen write it back as the keyword-only
marker. A stubgen whose parser has no such pattern is run unchanged.

Usage: python3 stubgen.py <stubgen arguments>
"""
import re
import sys

import mypy.stubdoc
from mypy.stubgen import main

_name = getattr(mypy.stubdoc, "_ARG_NAME_RE", None)
if _name is not None and not _name.match("*"):
    mypy.stubdoc._ARG_NAME_RE = re.compile(_name.pattern + r"|\*$")

if __name__ == "__main__":
    sys.exit(main())
