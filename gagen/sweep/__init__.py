"""Sweeps on Dask ``distributed`` (``gagen sweep``): kernels over many configurations (random or a regular
grid) and reaching problems over grids of targets, for any bundled cooperative system, chunked, resumable
and written as one Parquet file per chunk.

- ``problems``: what a chunk computes (``Manipulability``, ``Reach``); ``grid``: configuration grids;
  ``places``: where each row's primitive is (batched circumcircles and -spheres);
- ``store``: the output folder (atomic chunk files, the sweep's description, reading back);
- ``engine``: the run on a cluster (``run``) and the serial reference (``run_serial``);
- ``plots``: the reachability map and the ellipsoid-volume map; ``command``: the CLI.

Needs the ``sweep`` extra: ``pip install 'gagen[sweep]'``.
"""
