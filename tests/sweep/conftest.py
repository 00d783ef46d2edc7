"""One 2-worker LocalCluster for every sweep test module (starting one costs ≈ 1.5 s)."""

from __future__ import annotations

import pytest


@pytest.fixture(scope="package")
def client():
    pytest.importorskip("distributed")  # the sweep extra
    from gagen.sweep.engine import connect

    with connect(workers=2) as client:
        yield client
