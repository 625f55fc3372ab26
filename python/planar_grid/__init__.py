# SPDX-License-Identifier: BSD-3-Clause
"""PlanarGrid: planar surface-based 3D mapping for mobile robots.

Every class and function of the C++ extension ``planar_grid._planar_grid`` is available
here (``import planar_grid as pg; pg.PlanarGridMap``); ``help(planar_grid._planar_grid)``
gives the extension's own documentation. ``planar_grid.distributed`` (imported on its own,
it needs Dask's ``distributed``) maps a recording in segments on a Dask cluster and
merges the segment maps. See docs/PYTHON.md and docs/SCALE.md.
"""
from planar_grid import _planar_grid
from planar_grid._planar_grid import *  # noqa: F401,F403  (the extension's public names)

# The extension's dunder attributes (stubgen leaves them out of its stubs).
__version__: str = getattr(_planar_grid, "__version__")
__doc__ = _planar_grid.__doc__


def _constructor_signature(cls):
    """inspect.Signature of an extension class's constructor, read from the first line
    of the docstring pybind11 writes for it (``__init__(self: T, *, a: float = 0.1) ->
    None``), without ``self``; None for a class with several constructors or a default
    that is not a Python literal. The annotations are the type names pybind11 writes."""
    import ast
    import inspect

    doc = (cls.__init__.__doc__ or "").lstrip()
    first = doc.splitlines()[0] if doc else ""
    # Several constructors: pybind11's first line is "__init__(*args, **kwargs)".
    if not first.startswith("__init__(self: "):
        return None
    rest = first[len("__init__(self: "):].partition(",")[2]
    if not rest:
        return inspect.Signature([])
    try:
        tree = ast.parse("def f(" + rest.rsplit(") ->", 1)[0] + "): pass")
    except SyntaxError:
        return None
    args = tree.body[0].args
    P = inspect.Parameter
    parameters = []
    positional = args.posonlyargs + args.args
    defaults = [None] * (len(positional) - len(args.defaults)) + list(args.defaults)
    try:
        for arg, default in zip(positional, defaults):
            parameters.append(P(arg.arg, P.POSITIONAL_OR_KEYWORD,
                                default=P.empty if default is None
                                else ast.literal_eval(default),
                                annotation=ast.unparse(arg.annotation)))
        for arg, default in zip(args.kwonlyargs, args.kw_defaults):
            parameters.append(P(arg.arg, P.KEYWORD_ONLY,
                                default=P.empty if default is None
                                else ast.literal_eval(default),
                                annotation=ast.unparse(arg.annotation)))
    except ValueError:
        return None
    return inspect.Signature(parameters)


# inspect.signature() cannot read a pybind11 constructor; the classes whose signature
# the extension does not set get it from the constructor's generated docstring.
for _name in dir(_planar_grid):
    _cls = getattr(_planar_grid, _name)
    if isinstance(_cls, type) and not _name.startswith("_") \
            and "__signature__" not in vars(_cls):
        _signature = _constructor_signature(_cls)
        if _signature is not None:
            _cls.__signature__ = _signature
del _name, _cls, _signature
