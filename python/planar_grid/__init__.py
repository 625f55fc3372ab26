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
