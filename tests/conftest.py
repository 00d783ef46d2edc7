"""Shared test settings: the test tiers, hypothesis profiles and the algebras every test runs over.

Tiers: a plain ``pytest`` runs the fast tier, every test not marked ``slow``, ``compiling`` or
``realtime`` (see ``markers`` in pyproject.toml); ``pytest --full`` (or GAGEN_TESTS=full) runs them
all, as CI does. An explicit ``-m`` expression, or a test named by its node id (``file::test``),
selects by itself, whatever the tier: ``pytest -m compiling`` runs the compiling tests."""

import os
import signal
import subprocess
from collections.abc import Iterator
from contextlib import contextmanager
from functools import cache
from pathlib import Path

import pytest
from hypothesis import HealthCheck, settings

from gagen.algebra.signature import cga2d, cga3d, ga3d, pga3d

settings.register_profile("ci", deadline=None, suppress_health_check=[HealthCheck.too_slow], derandomize=True)
settings.register_profile("dev", deadline=None, suppress_health_check=[HealthCheck.too_slow])
# derandomized by default, so CI runs exactly the examples every local run has passed; set
# GAGEN_HYPOTHESIS=dev to explore fresh random examples (and keep any failure in .hypothesis/)
settings.load_profile(os.environ.get("GAGEN_HYPOTHESIS", "ci"))

TIER_MARKERS = ("slow", "compiling", "realtime")  # left out of the fast (default) tier


def pytest_addoption(parser):
    parser.addoption("--full", action="store_true", default=False,
                     help="run the full tier: also the tests marked slow, compiling or realtime "
                          "(the default is the fast tier; GAGEN_TESTS=full does the same)")


def _full_tier(config) -> bool:
    return config.getoption("--full") or os.environ.get("GAGEN_TESTS", "").strip().lower() == "full"


def _tier_applies(config) -> bool:
    """The fast tier filters unless the full tier is asked for, an explicit -m expression selects, or
    the command line names single tests (``path::name``)."""
    return not (_full_tier(config) or config.getoption("markexpr")
                or any("::" in str(arg) for arg in config.args))


# The committed generated modules the fast tier uses the C kernels of. A module is built on first use
# (``bundled_module``: a fresh clone has no CasADi files, so the committed ones are rebuilt, to the same
# bytes, and compiled: ≈ 5 s panda_point, ≈ 15 s three_pandas_circle on a 2-core VM; every other bundled
# module is built into the gagen cache, 5-30 s), so a test that needs any other module is ``compiling``.
FAST_MODULES = frozenset({"panda_point", "three_pandas_circle", "three_iiwas_circle"})

REPO = Path(__file__).resolve().parents[1]
# every bundled source by module name: each app's specs and the example Python files of kernels
BUNDLED = {path.stem: path for pattern in ("gagen/apps/*/robots/*.yaml", "examples/*.py")
           for path in sorted(REPO.glob(pattern))}
# The bundled sources that between them cover every primitive kind and every feature of the kernels (one
# chain; shared joints; mimic joints; 3 and 4 chains; a best-fit sphere (the best-fit circle's eigen solve
# is held to the interpreter in C by test_build.py); every other application; the smallest and the
# largest linkage). The backends that re-print a
# module whose C kernels tests/codegen/test_build.py holds to the interpreter on every bundled system
# (JAX, the CUDA host bodies) are held to C on these: the others add no new kind of graph, and checking
# them too cost about 170 s of the full tier's CPU time.
BACKEND_MODULES = tuple(sorted({
    "panda_point", "two_pandas_point_pair", "g1_arms_line", "three_pandas_circle", "three_iiwas_plane",
    "leap_hand_sphere", "leap_hand_palm_sphere", "hexapod", "stereo_rig", "four_bar", "ten_bar", "formulas",
    "interpolation"}))
assert set(BACKEND_MODULES) <= set(BUNDLED), set(BACKEND_MODULES) - set(BUNDLED)


def bundled_module(name: str):
    """The generated module of the bundled source ``name``, loaded: built on first use where
    ``gagen.modules`` puts it (the committed ``generated/<name>``, else the gagen cache, which the test
    workers share: a module is built once per run, concurrent builds of it wait on its lock), once
    per process. Call it in tests or fixtures, never at collection."""
    from gagen.modules import bundled_module as built

    return built(BUNDLED[name])


@cache
def committed_modules() -> tuple[str, ...]:
    """The modules committed under generated/ (git's list; without git, the folders with a manifest)."""
    try:
        listed = subprocess.run(["git", "ls-files", "-z", "generated"], cwd=REPO, capture_output=True,
                                check=True).stdout.decode().split("\0")
        names = {Path(path).parts[1] for path in listed if Path(path).name == "manifest.json"}
    except (OSError, subprocess.CalledProcessError):
        names = {p.parent.name for p in (REPO / "generated").glob("*/manifest.json")}
    return tuple(sorted(names))


def tiered(values, fast, *marks):
    """Parametrize values with the tier marks (``slow`` unless others are given) on all but those in
    ``fast``: the fast tier keeps a representative few, the full tier runs all. A tuple value is one
    test's several arguments. The test ids are those of the plain values."""
    marks = marks or (pytest.mark.slow,)
    fast = set(fast)
    return [value if value in fast else
            pytest.param(*(value if isinstance(value, tuple) else (value,)), marks=marks)
            for value in values]


def pytest_report_header(config):
    if _tier_applies(config):
        return (f"gagen tier: fast (tests marked {', '.join(TIER_MARKERS)} deselected; "
                "--full or GAGEN_TESTS=full runs them)")
    return "gagen tier: full" if _full_tier(config) else "gagen tier: as selected (-m or node ids)"


def pytest_collection_modifyitems(config, items):
    if not _tier_applies(config):
        return
    kept, deselected = [], []
    for item in items:
        (deselected if any(item.get_closest_marker(m) for m in TIER_MARKERS) else kept).append(item)
    if deselected:
        config.hook.pytest_deselected(items=deselected)
        items[:] = kept
    config.stash[_LEFT_OUT] = len(deselected)


_LEFT_OUT = pytest.StashKey[int]()


def pytest_terminal_summary(terminalreporter, config):
    left_out = config.stash.get(_LEFT_OUT, 0)
    if left_out:
        terminalreporter.write_line(f"fast tier: {left_out} tests marked {'/'.join(TIER_MARKERS)} left out; "
                                    "pytest --full (or GAGEN_TESTS=full) runs them too")


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


@pytest.fixture(autouse=True, scope="session")
def _private_compile_cache(request, tmp_path_factory):
    """gagen.compile and the bundled modules cache into $GAGEN_CACHE (else ~/.cache/gagen): the tests use
    their own folder, pytest's cache (``.pytest_cache/d/gagen``, shared by the pytest-xdist workers and
    kept between runs, so the edit-test loop builds a module again only when its build key changes;
    ``--cache-clear`` empties it), or a fresh temporary one without the cache plugin. Builds of one
    folder wait for each other on its lock."""
    if "GAGEN_CACHE" not in os.environ:
        cache = getattr(request.config, "cache", None)
        if cache is not None:
            folder = cache.mkdir("gagen")
        elif os.environ.get("PYTEST_XDIST_WORKER"):  # the workers' temporary folders share a parent
            folder = tmp_path_factory.getbasetemp().parent / "gagen-cache"
            folder.mkdir(exist_ok=True)
        else:
            folder = tmp_path_factory.mktemp("gagen-cache")
        os.environ["GAGEN_CACHE"] = str(folder)
    yield
