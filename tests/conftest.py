"""Shared test settings: hypothesis profiles and the algebras every test runs over."""

import os

import pytest
from hypothesis import HealthCheck, settings

from gagen.algebra.signature import cga2d, cga3d, ga3d, pga3d

settings.register_profile("ci", deadline=None, suppress_health_check=[HealthCheck.too_slow], derandomize=True)
settings.register_profile("dev", deadline=None, suppress_health_check=[HealthCheck.too_slow])
settings.load_profile("ci" if os.environ.get("CI") else "dev")

ALGEBRAS = {"cga3d": cga3d(), "cga2d": cga2d(), "pga3d": pga3d(), "ga3d": ga3d()}


@pytest.fixture(params=sorted(ALGEBRAS))
def algebra(request):
    return ALGEBRAS[request.param]
