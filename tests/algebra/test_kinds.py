"""Kinds per algebra (``gagen.algebra.kinds``): the cga3d kinds are the model's blade groups, every
kind's blades belong to its algebra, and the front-end's random samples of a versor kind are unit
versors of that kind."""

from __future__ import annotations

import numpy as np
import pytest

from gagen.algebra.kinds import kind_blades, kinds
from gagen.algebra.signature import cga2d, cga3d, ga3d, pga3d
from gagen.frontend import _declaration, _sample_input
from gagen.interp import MultiVector
from gagen.model.conformal import MOTOR, MOTOR_GENERATOR, POINT, SIMILARITY, SIMILARITY_GENERATOR

ALGEBRAS = (cga3d(), cga2d(), pga3d(), ga3d())


def test_cga3d_kinds_are_the_model_blade_groups():
    table = kinds(cga3d())
    assert table["motor"] == MOTOR and table["point"] == POINT and table["similarity"] == SIMILARITY
    assert table["line_bivector"] == MOTOR_GENERATOR and table["similarity_generator"] == SIMILARITY_GENERATOR
    assert len(table["line"]) == 6 and len(table["circle"]) == 10 and len(table["plane"]) == 4
    assert len(table["sphere"]) == 5 and len(table["point_pair"]) == 10


@pytest.mark.parametrize("algebra", ALGEBRAS, ids=lambda a: a.name)
def test_every_kind_is_made_of_the_algebras_blades_in_bit_order(algebra):
    for name, blades in kinds(algebra).items():
        masks = [algebra.blade(b) for b in blades]
        assert masks == sorted(set(masks)), name


def test_an_unknown_kind_names_the_known_ones():
    with pytest.raises(KeyError, match="motor"):
        kind_blades(pga3d(), "sphere")


@pytest.mark.parametrize(("algebra", "kind"), [(a, k) for a in ALGEBRAS for k in ("rotor", "motor")
                                                   if k in kinds(a)]
                         + [(cga3d(), "similarity"), (cga2d(), "translator")], ids=str)
def test_sampled_versors_are_unit_versors_of_their_kind(algebra, kind):
    rng = np.random.default_rng(3)
    declaration = _declaration(algebra, kind, "test", "x")
    for _ in range(5):
        values = _sample_input(algebra, declaration, rng)
        v = MultiVector.from_blades(algebra, dict(zip(declaration.blades, values, strict=True)))
        product = v * ~v
        if kind == "similarity":  # V V~ = 1 for the motor part; the dilator scales: V V~ is a scalar
            assert np.allclose(product.coeffs[1:], 0, atol=1e-12)
        else:
            assert product[0] == pytest.approx(1.0, abs=1e-12)
            assert np.allclose(product.coeffs[1:], 0, atol=1e-12)
