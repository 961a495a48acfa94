"""Shared helpers of the Python tests: the command line binary, the repository, temporary folders,
and the statistical check (a mean against its expectation within 4 standard errors)."""
import os
import pathlib

import numpy as np
import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
SHARED = pathlib.Path(os.environ.get("SPECTRACK_SHARED_DATA", ROOT.parent / "shared" / "data" / "vdb"))


@pytest.fixture
def spectrack_binary():
    path = os.environ.get("SPECTRACK_BINARY", str(ROOT / "build" / "spectrack"))
    if not os.access(path, os.X_OK):
        pytest.fail(f"{path}: the spectrack binary is missing (set SPECTRACK_BINARY)")
    return path


def mean_and_se(values):
    """The mean of independent values (pixels) and its standard error."""
    v = np.asarray(values, dtype=np.float64).ravel()
    return v.mean(), v.std(ddof=1) / np.sqrt(v.size)


def within_4se(values, expected):
    m, se = mean_and_se(values)
    return abs(m - expected) <= 4 * se, m, se
