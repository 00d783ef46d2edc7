"""A 3D viewer in the browser: the robots of a cooperative system and their primitive, live (viser).

- ``Scene(system)``: a viser server on the loopback interface drawing the chains and the primitive;
  ``update(q)``, ``play(times, qs)``, ``show_primitive(False)``, ``url``; ``serve(scene, runs)`` plays
  trajectories in a loop (the demos' ``--view``).
- ``render(scene)`` / ``export_png(system, q, path)`` / ``export_frames(system, qs, folder)``: frames drawn by
  headless Chromium, as pixels or PNGs.
- ``geometry``: the drawn shapes in numpy (joint frames along each chain, the primitive through points);
  ``camera``: the pinhole camera that says where things land in a render.
- ``visuals``: ``load_visuals(spec, system)``, the URDFs' ``<visual>`` meshes and shapes of each chain's
  links, placed per link (``Scene(..., visuals=...)`` draws them instead of sticks).
- ``access``: the server answers only the holder of the per-run token in ``Scene.url`` (or of the
  cookie its page sets), through a loopback Host, from its own Origin: no other web page gets in.
- ``command``: ``gagen view`` / ``python -m gagen.viewer``.

viser is an optional dependency (the ``viewer`` extra), imported when a Scene starts. The names above
load on first use, so that the command line can import ``gagen.viewer.command`` cheaply.
"""

from typing import Any

from gagen.arguments import DEFAULT_VIEWER_PORT as DEFAULT_PORT  # one default, the verbs'

_EXPORTS = {"Scene": "scene", "serve": "scene", "render": "browser", "export_png": "browser",
            "export_frames": "browser", "find_chromium": "browser", "Camera": "camera", "framing": "camera",
            "Shape": "geometry", "shape": "geometry", "system_pose": "geometry", "load_visuals": "visuals"}
__all__ = ["DEFAULT_PORT", *sorted(_EXPORTS)]


def __getattr__(name: str) -> Any:
    if name in _EXPORTS:
        from importlib import import_module

        return getattr(import_module(f"gagen.viewer.{_EXPORTS[name]}"), name)
    raise AttributeError(f"module 'gagen.viewer' has no attribute {name!r}")
