"""Code generation: what the backends take (``ir``: kernels, ports, a module's source), the backends
(``backends/<name>/``, each with its printer, templates and loader), the escaping filters of the
templates (``escape``) and the system C compiler (``compiler``)."""
