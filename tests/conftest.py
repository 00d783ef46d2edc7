"""Shared test settings: hypothesis profiles and the algebras every test runs over."""

import os
import signal
from collections.abc import Iterator
from contextlib import contextmanager

import pytest
from hypothesis import HealthCheck, settings

from gagen.algebra.signature import cga2d, cga3d, ga3d, pga3d

settings.register_profile("ci", deadline=None, suppress_health_check=[HealthCheck.too_slow], derandomize=True)
settings.register_profile("dev", deadline=None, suppress_health_check=[HealthCheck.too_slow])
# derandomized by default, so CI runs exactly the examples every local run has passed; set
# GAGEN_HYPOTHESIS=dev to explore fresh random examples (and keep any failure in .hypothesis/)
settings.load_profile(os.environ.get("GAGEN_HYPOTHESIS", "ci"))

ALGEBRAS = {"cga3d": cga3d(), "cga2d": cga2d(), "pga3d": pga3d(), "ga3d": ga3d()}


@pytest.fixture(params=sorted(ALGEBRAS))
def algebra(request):
    return ALGEBRAS[request.param]


def far_from_null_vectors(algebra, count: int = 4):
    """Strategy: ``count`` vectors, each dominated by one Euclidean basis vector (so v·v >= 0.5)."""
    import numpy as np
    from hypothesis import strategies as st
    from hypothesis.extra.numpy import arrays

    euclid = [i for i, label in enumerate(algebra.vector_labels) if label not in ("0", "inf")]
    small = arrays(np.float64, (count, algebra.dimension),
                   elements=st.floats(-0.3, 0.3, allow_subnormal=False))
    dominant = st.lists(st.tuples(st.sampled_from(euclid), st.floats(1, 2), st.sampled_from([-1.0, 1.0])),
                        min_size=count, max_size=count)

    def build(parts):
        rows, picks = parts
        rows = rows.copy()
        for row, (i, size, sign) in zip(rows, picks, strict=True):
            row[i] += sign * size
        return rows

    return st.tuples(small, dominant).map(build)


def versor_from_vectors(algebra, vectors):
    """Interpreter multivector: the product of the given vectors."""
    from gagen.interp import MultiVector

    v = MultiVector.from_blades(algebra, {0: 1.0})
    for row in vectors:
        v = v * MultiVector.from_blades(algebra, dict(zip(algebra.blades_of_grade(1), row, strict=True)))
    return v


@contextmanager
def deadline(seconds: float) -> Iterator[None]:
    """Raise TimeoutError in the test if the body runs longer: a case that used to hang fails instead."""
    def expire(signum, frame):
        raise TimeoutError(f"still running after {seconds} s")
    previous = signal.signal(signal.SIGALRM, expire)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)
