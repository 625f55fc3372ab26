# SPDX-License-Identifier: BSD-3-Clause
"""Shared fixtures of the planar_grid Python tests (run by CTest with the module's build
folder on PYTHONPATH and the data and source folders in the environment)."""

import os
import pathlib
from typing import Optional

import numpy as np
import numpy.typing as npt
import pytest

SOURCE_DIR = pathlib.Path(
    os.environ.get("PLANAR_GRID_SOURCE_DIR", pathlib.Path(__file__).resolve().parents[2]))
DATA_DIR = pathlib.Path(os.environ.get("PLANAR_GRID_DATA_DIR", SOURCE_DIR / ".." / "shared" / "data"))


@pytest.fixture
def data_dir() -> pathlib.Path:
    """The real sensor data (../shared/data); read, never copied."""
    if not DATA_DIR.is_dir():
        pytest.fail(f"the shared data folder {DATA_DIR} is missing (PLANAR_GRID_DATA_DIR)")
    return DATA_DIR


@pytest.fixture
def source_dir() -> pathlib.Path:
    """The repository."""
    return SOURCE_DIR


def plane_patch(normal: npt.ArrayLike, d: float, size_m: float, spacing_m: float,
                rng: Optional[np.random.Generator] = None,
                noise_m: float = 0.0) -> npt.NDArray[np.float64]:
    """Points on the plane n . x + d = 0 (n unit): a square grid of side size_m around the
    plane's point nearest the origin, with Gaussian noise along n (sigma noise_m)."""
    n: npt.NDArray[np.float64] = np.asarray(normal, dtype=float)
    n = n / np.linalg.norm(n)
    helper = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(n, helper)
    u /= np.linalg.norm(u)
    v = np.cross(n, u)
    steps = np.arange(-size_m / 2, size_m / 2 + 1e-9, spacing_m)
    a, b = np.meshgrid(steps, steps)
    points: npt.NDArray[np.float64] = -d * n + a.reshape(-1, 1) * u + b.reshape(-1, 1) * v
    if noise_m > 0.0:
        assert rng is not None, "noise_m > 0 needs rng"
        points += rng.normal(0.0, noise_m, size=(len(points), 1)) * n
    return points
