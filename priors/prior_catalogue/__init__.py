"""The built-in prior models, one module per prior.

Every public module of this package exports ``NAME`` (the prior's name, e.g. ``"tilt-drag"``),
``ORDER`` (its place in listings) and ``FACTORY`` (``FACTORY(**params) -> PriorModel``);
:data:`priors.registry.PRIORS` finds them. Adding a built-in prior is one new module here plus its
test (docs/extending.md). Modules whose name starts with ``_`` are not priors.
"""
