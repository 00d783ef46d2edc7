"""Named kinds of multivector per algebra: which blades a point, a motor, a plane … may have.

A kernel declares each input (and, if it wants fixed rows, each output) by a kind of its algebra;
the kind gives the blades, in the algebra's bitmask order, that become the port's rows. Every
algebra has the generic kinds (``scalar``, ``vector``, ``bivector``, ``trivector``, ``even``,
``odd``, ``multivector``, ``grade<k>``); the presets add their geometric ones:

- cga3d (OPNS, null basis e0, e1, e2, e3, e∞): point, rotor, translator, motor, dilator,
  similarity, point_pair, line, circle, plane, sphere, line_bivector (a motor generator), and
  similarity_generator;
- cga2d: point, rotor, translator, motor, dilator, point_pair, line, circle;
- pga3d (e0² = 0; planes are vectors, points trivectors): plane, line, point, rotor, translator,
  motor;
- ga3d: rotor.
"""

from __future__ import annotations

from functools import cache

from gagen.algebra.signature import Algebra

# "scalar" is a plain scalar (not a multivector); the others are multivectors on these blades
SCALAR = "scalar"


def _grade(algebra: Algebra, *grades: int) -> tuple[str, ...]:
    return tuple(algebra.blade_name(m) for m in range(algebra.size) if m.bit_count() in grades)


def _with(algebra: Algebra, grade: int, label: str, present: bool = True) -> tuple[str, ...]:
    """Blades of one grade that contain (or do not contain) the basis vector ``label``."""
    bit = 1 << algebra.vector_labels.index(label)
    return tuple(algebra.blade_name(m) for m in range(algebra.size)
                 if m.bit_count() == grade and bool(m & bit) == present)


def _ordered(algebra: Algebra, names: tuple[str, ...]) -> tuple[str, ...]:
    return tuple(sorted(set(names), key=algebra.blade))


def _generic(algebra: Algebra) -> dict[str, tuple[str, ...]]:
    n = algebra.dimension
    kinds = {"vector": _grade(algebra, 1), "bivector": _grade(algebra, 2),
             "even": _grade(algebra, *range(0, n + 1, 2)), "odd": _grade(algebra, *range(1, n + 1, 2)),
             "multivector": _grade(algebra, *range(n + 1)), "pseudoscalar": _grade(algebra, n)}
    if n >= 3:
        kinds["trivector"] = _grade(algebra, 3)
    kinds.update({f"grade{k}": _grade(algebra, k) for k in range(n + 1)})
    return kinds


def _conformal(algebra: Algebra) -> dict[str, tuple[str, ...]]:
    euclid = tuple(f"e{label}" for label in algebra.vector_labels[1:-1])
    rotation = tuple(b for b in _grade(algebra, 2) if "0" not in b and "inf" not in b)
    translation = tuple(f"{e}inf" for e in euclid)
    kinds = {
        "vector": euclid,  # a Euclidean direction (in cga, "vector" means that, not any grade-1 vector)
        "conformal_vector": _grade(algebra, 1),
        "point": _grade(algebra, 1),
        "rotor": ("1", *rotation),
        "translator": ("1", *translation),
        # in 3D a screw motion also has the e123∞ part (rotation and translation along its axis)
        "motor": _ordered(algebra, ("1", *rotation, *translation, *(("e123inf",) * (len(euclid) == 3)))),
        "dilator": ("1", "e0inf"),
        "point_pair": _grade(algebra, 2),
        "line": _with(algebra, 3, "inf"),
        "circle": _grade(algebra, 3),
        "line_bivector": _ordered(algebra, (*rotation, *translation)),
        "similarity_generator": _ordered(algebra, (*rotation, "e0inf", *translation)),
    }
    if len(euclid) == 3:
        kinds["plane"] = _with(algebra, 4, "inf")
        kinds["sphere"] = _grade(algebra, 4)
    # a similarity: a motor times a dilator (the even blades those products reach)
    kinds["similarity"] = _ordered(algebra, (*kinds["motor"], "e0inf", *(
        b for b in _grade(algebra, 4) if "0" in b and "inf" in b)))
    return kinds


def _pga3d(algebra: Algebra) -> dict[str, tuple[str, ...]]:
    rotation = ("e12", "e13", "e23")
    translation = ("e01", "e02", "e03")
    return {"plane": _grade(algebra, 1), "line": _grade(algebra, 2), "point": _grade(algebra, 3),
            "rotor": ("1", *rotation), "translator": ("1", *translation),
            "motor": _ordered(algebra, ("1", *rotation, *translation, "e0123"))}


def _ga3d(algebra: Algebra) -> dict[str, tuple[str, ...]]:
    return {"rotor": ("1", *_grade(algebra, 2))}


_PRESETS = {"cga3d": _conformal, "cga2d": _conformal, "pga3d": _pga3d, "ga3d": _ga3d}


@cache
def kinds(algebra: Algebra) -> dict[str, tuple[str, ...]]:
    """Every kind of ``algebra`` by name (the generic ones, then the preset's), with its blades."""
    table = _generic(algebra)
    if algebra.name in _PRESETS:
        table.update(_PRESETS[algebra.name](algebra))
    return table


def kind_blades(algebra: Algebra, kind: str) -> tuple[str, ...]:
    """The blades of ``kind`` in ``algebra``; a KeyError naming the known kinds otherwise."""
    table = kinds(algebra)
    if kind not in table:
        raise KeyError(f"algebra {algebra.name} has no kind {kind!r}; known: {SCALAR}, "
                       f"{', '.join(sorted(table))}")
    return table[kind]
