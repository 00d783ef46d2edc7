"""Your own formulas as kernels: three plain Python functions over multivectors (README, "Your own formula").

Build them into a module with ``gagen build examples/formulas.py`` (written to generated/formulas/),
or compile one in-process with ``gagen.compile(circle_distance)``.
"""

import gagen
from gagen.kinds import circle, motor, plane, point
from gagen.model.conformal import location
from gagen.model.primitives import centre, radius, unit_normal


@gagen.kernel(algebra="cga3d")
def circle_through(A: point, B: point, C: point):
    """The circle through three points: A ∧ B ∧ C."""
    return {"circle": A ^ B ^ C}


@gagen.kernel(algebra="cga3d", jacobians={"J_d": ("d", "X")})
def circle_distance(X: point, C: circle):
    """Distance of a point from a circle: sqrt(h² + (ρ − r)²), h above its plane, ρ from its axis."""
    m = X.math
    v = location(X) - location(centre(C))
    h = v.sp(unit_normal(C))
    rho = m.sqrt(v.sp(v) - h * h)
    r = radius(C)
    return {"d": m.sqrt(h * h + (rho - r) * (rho - r))}


@gagen.kernel(algebra="cga3d")
def plane_meet(A: plane, B: plane):
    """The line where two planes meet: their regressive product A ∨ B."""
    return {"line": A & B}


@gagen.kernel(algebra="pga3d")
def move_point(M: motor, X: point):
    """A PGA motor acting on a point: M X M~."""
    return {"moved": M.sandwich(X)}
