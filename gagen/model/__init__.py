"""The geometric program: every formula of gagen written once against the multivector protocol
(``gagen.algebra.protocol.Multivector``, the type of every multivector argument here).

Run on ``gagen.interp.MultiVector`` it is the reference interpreter's path; run on
``gagen.algebra.SparseMultivector`` it flattens to CasADi SX. Modules: ``conformal`` (points,
blade groups), ``guarded`` (NaN-free special functions), ``versors`` (exp/log charts, versors
between objects), ``primitives`` (constructors and queries), ``similarity`` (V_S between
primitives and the cooperative V_Sc).
"""
