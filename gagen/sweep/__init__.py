"""Sweeps on Dask ``distributed`` (``gagen sweep``): kernels over many configurations and reaching
problems over grids of targets, chunked, resumable and written as one Parquet file per chunk.

- ``problems``: what a chunk computes (``Manipulability``, ``Reach``);
- ``store``: the output folder (atomic chunk files, the sweep's description, reading back);
- ``engine``: the run on a cluster (``run``) and the serial reference (``run_serial``);
- ``plots``: the reachability map and the manipulability map; ``command``: the CLI.

Needs the ``sweep`` extra: ``pip install 'gagen[sweep]'``.
"""
