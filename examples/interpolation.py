"""Interpolating two primitives through their similarity versors [COOP Fig. 4] as kernels.

Each ``interpolate_<kind>`` takes two primitives X1, X2 of the kind (blades) and t, and returns
X(t) = V(t) X_u V(t)~ (``gagen.model.interpolation``), the conditioning of the pair, and dX/dt by AD.
Build them with ``gagen build examples/interpolation.py --check`` (to generated/interpolation/).
"""

import numpy as np

import gagen
from gagen.algebra.kinds import kind_blades
from gagen.algebra.signature import cga3d
from gagen.control import goals
from gagen.kinds import circle, line, plane, point, point_pair, scalar, sphere
from gagen.model.interpolation import interpolate


def _sample(kind):
    """Random inputs for the checks: two primitives of ``kind`` (centres in a 1 m cube, radii 0.2-1 m,
    random unit directions) and t in [0, 1]."""
    rows = kind_blades(cga3d(), kind)

    def primitive(rng):
        c, n, r = rng.uniform(-1, 1, 3), rng.normal(size=3), rng.uniform(0.2, 1.0)
        makers = {"point": lambda: goals.point(c), "line": lambda: goals.line(c, n),
                  "point_pair": lambda: goals.point_pair(c - r * n, c + r * n),
                  "circle": lambda: goals.circle(c, r, n), "plane": lambda: goals.plane(c, n),
                  "sphere": lambda: goals.sphere(c, r)}
        versor = makers[kind]()  # V_S(X_u, X), then X = V X_u V~
        x = goals.primitive(kind, versor)
        return np.array([x[b] for b in rows])

    return lambda rng: [primitive(rng), primitive(rng), rng.uniform(0.0, 1.0, 1)]


def _declared(kind):
    return {"algebra": "cga3d", "outputs": {"X": kind, "conditioning": "scalar"},
            "jacobians": {"dX_dt": ("X", "t")}, "sample": _sample(kind)}


def _values(kind, X1, X2, t):
    x, _, conditioning = interpolate(kind, X1, X2, t)
    return {"X": x, "conditioning": conditioning}


@gagen.kernel(**_declared("point"))
def interpolate_point(X1: point, X2: point, t: scalar):
    """X(t) between two points (a straight line at constant speed) and dX/dt."""
    return _values("point", X1, X2, t)


@gagen.kernel(**_declared("point_pair"))
def interpolate_point_pair(X1: point_pair, X2: point_pair, t: scalar):
    """X(t) between two point pairs and dX/dt."""
    return _values("point_pair", X1, X2, t)


@gagen.kernel(**_declared("line"))
def interpolate_line(X1: line, X2: line, t: scalar):
    """X(t) between two lines (a screw motion) and dX/dt."""
    return _values("line", X1, X2, t)


@gagen.kernel(**_declared("circle"))
def interpolate_circle(X1: circle, X2: circle, t: scalar):
    """X(t) between two circles and dX/dt."""
    return _values("circle", X1, X2, t)


@gagen.kernel(**_declared("plane"))
def interpolate_plane(X1: plane, X2: plane, t: scalar):
    """X(t) between two planes and dX/dt."""
    return _values("plane", X1, X2, t)


@gagen.kernel(**_declared("sphere"))
def interpolate_sphere(X1: sphere, X2: sphere, t: scalar):
    """X(t) between two spheres and dX/dt."""
    return _values("sphere", X1, X2, t)
