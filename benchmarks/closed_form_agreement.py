"""The closed-form circle similarity Jacobian [COOP Appendix B] against the AD one, at random configurations.

    python benchmarks/closed_form_agreement.py                 # 200 configurations per system
    python benchmarks/closed_form_agreement.py --count 20 --png /tmp/agreement.png

For the bundled three-Panda and three-iiwa circle systems, draws configurations uniformly within the joint
limits, compares J_A from ``gagen.apps.cooperative.closed_form`` (interpreter and traced CasADi Function) with
``similarity_jacobians``'s AD J_A, prints the worst and median relative errors and the op counts, and writes
the figure of docs/closed-form-jacobians.md (docs/images/closed_form_agreement.png).
"""

import argparse
import time
from pathlib import Path

import numpy as np

from gagen.apps.cooperative.catalogue import kernel_functions
from gagen.apps.cooperative.closed_form import TERMS, agreement, agreement_figure, similarity_closed_form
from gagen.robots.spec import load_system

ROOT = Path(__file__).resolve().parents[1]
SYSTEMS = ("three_pandas_circle", "three_iiwas_circle")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--count", type=int, default=200, help="random configurations per system")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--png", default=str(ROOT / "docs/images/closed_form_agreement.png"))
    args = parser.parse_args()
    results = []
    for name in SYSTEMS:
        system, _ = load_system(ROOT / "robots" / f"{name}.yaml")
        start = time.perf_counter()
        result = agreement(system, args.count, args.seed)
        seconds = time.perf_counter() - start
        closed = similarity_closed_form(system).trace().op_count
        ad = kernel_functions(system)["similarity_jacobians"].trace().op_count
        print(f"{name}: {args.count} configurations in {seconds:.1f} s")
        for label, errors in (("interpreter", result.interpreter), ("CasADi", result.casadi)):
            print(f"  {label:11} max {errors.max():.2e}  median {np.median(errors):.2e}")
        print("  terms (median of max |term| / max |J_A|): "
              + ", ".join(f"{t} {np.median(result.terms[:, j]):.2f}" for j, t in enumerate(TERMS)))
        print(f"  flops: closed form {closed.flops}, similarity_jacobians (AD; also log V, J_B) {ad.flops}")
        results.append(result)
    print("figure:", agreement_figure(results, args.png))


if __name__ == "__main__":
    main()
