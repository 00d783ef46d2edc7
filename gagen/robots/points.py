"""The end points of a multi-chain robot from its generated module: each chain's ``<chain>_fk`` kernel on
that chain's joints, picked from q by the kernel's row labels (chains may share joints: a humanoid's
waist drives both of its arms)."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray


def chain_kernels(manifest: dict[str, Any]) -> list[tuple[str, list[int]]]:
    """Per chain, in order: (its ``<chain>_fk`` kernel, the index in q of each of its joints)."""
    joints = {name: i for i, name in enumerate(manifest["joints"])}
    return [(entry["name"], [joints[row] for row in entry["inputs"][0]["rows"]])
            for entry in manifest["kernels"] if entry["name"].endswith("_fk")]


def end_points(module: Any, q: ArrayLike) -> NDArray[np.float64]:
    """Each chain's Euclidean end point: (chains, 3) for one configuration q (dof,), (n, chains, 3) for
    the rows of q (n, dof), through the batched kernels. The point's rows are e0 e1 e2 e3 e∞; its
    Euclidean part is e1 e2 e3 over the e0 weight."""
    q = np.asarray(q, dtype=np.float64)
    kernels = chain_kernels(module.manifest)
    if q.ndim == 1:
        points = [np.asarray(getattr(module.c, name)(q[indices])[1], dtype=np.float64).ravel()
                  for name, indices in kernels]
        return np.array([p[1:4] / p[0] for p in points])
    columns = [np.asarray(getattr(module.c, name).batch(np.ascontiguousarray(q[:, indices]))[1])
               for name, indices in kernels]
    return np.stack([p[:, 1:4] / p[:, :1] for p in columns], axis=1)
