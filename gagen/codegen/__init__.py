"""Code generation: C source from flat CasADi graphs, rendered through the jinja2 templates."""
