"""identify, one stage per module: :mod:`.settings` -> :mod:`.plan` (prior, input offset,
effects) -> :mod:`.problem` (datasets, prior features, constraints) -> :mod:`.search` (SNGP runs)
-> :mod:`.ladder` (guards, the final rung) -> :mod:`.pipeline` (the composition and its typed
result); :mod:`.study` repeats it over variants."""
