"""Declarations to annotate kernel arguments with: ``def f(X: point, C: circle)``.

Each name stands for the kind of the same name of the kernel's algebra (``gagen.algebra.kinds``),
resolved when the kernel is declared, so one set of names serves every algebra (a pga3d ``point``
is a trivector, a cga3d ``point`` a conformal vector). ``algebra`` marks the argument that receives
the zero multivector of the path the function runs on. Strings (``X: "point"``) work too; these
names keep linters from reading the annotations as undefined forward references. The front-end
(``gagen.frontend``) reads them; :class:`Declaration` is defined here, below it, so that these names
need nothing above the algebra.
"""

from __future__ import annotations

from dataclasses import dataclass

from gagen.algebra.kinds import SCALAR

ALGEBRA = "algebra"  # the declaration of the context argument


@dataclass(frozen=True)
class Declaration:
    """What one argument or output of a kernel is (``gagen.frontend``): a multivector on ``blades``
    (``kind`` names where they came from; a kind name alone, as below, is resolved against the kernel's
    algebra), ``size`` scalars (``single``: one bare scalar), or the algebra context; ``cols`` > 1 for
    a matrix output (a list of that many columns)."""

    kind: str
    blades: tuple[str, ...] = ()
    size: int = 0
    single: bool = False
    labels: tuple[str, ...] | None = None
    cols: int = 1

    @property
    def is_multivector(self) -> bool:
        return self.kind not in (SCALAR, "scalars", ALGEBRA)


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
