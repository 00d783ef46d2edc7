"""Declarations to annotate kernel arguments with: ``def f(X: point, C: circle)``.

Each name stands for the kind of the same name of the kernel's algebra (``gagen.algebra.kinds``),
resolved when the kernel is declared, so one set of names serves every algebra (a pga3d ``point``
is a trivector, a cga3d ``point`` a conformal vector). ``algebra`` marks the argument that receives
the zero multivector of the path the function runs on. Strings (``X: "point"``) work too; these
names keep linters from reading the annotations as undefined forward references.
"""

from gagen.frontend import Declaration

_NAMES = ("scalar", "vector", "bivector", "trivector", "even", "odd", "multivector", "pseudoscalar",
          "point", "rotor", "translator", "motor", "dilator", "similarity", "point_pair", "line",
          "circle", "plane", "sphere", "line_bivector", "similarity_generator", "conformal_vector",
          "algebra")

scalar = Declaration("scalar", size=1, single=True)
algebra = Declaration("algebra")
vector, bivector, trivector, even, odd, multivector, pseudoscalar = (
    Declaration(n) for n in ("vector", "bivector", "trivector", "even", "odd", "multivector", "pseudoscalar"))
point, rotor, translator, motor, dilator, similarity = (
    Declaration(n) for n in ("point", "rotor", "translator", "motor", "dilator", "similarity"))
point_pair, line, circle, plane, sphere = (
    Declaration(n) for n in ("point_pair", "line", "circle", "plane", "sphere"))
line_bivector, similarity_generator, conformal_vector = (
    Declaration(n) for n in ("line_bivector", "similarity_generator", "conformal_vector"))

__all__ = list(_NAMES)
