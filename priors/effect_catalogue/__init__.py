"""The built-in effects of the diagnosis, one module per effect.

Every public module of this package exports ``EFFECT = Effect(...)`` (:class:`priors.effects.Effect`)
and is named after the effect's id; :data:`priors.effects.CATALOGUE` finds them on first use and
orders them by ``Effect.order`` (the order in which the diagnosis tries them). Adding a built-in
effect is one new module here plus its test (docs/extending.md). Modules whose name starts with
``_`` are not effects.
"""
