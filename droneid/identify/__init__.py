"""identify, one stage per module, under the plan of :mod:`droneid.planning` (shared with
diagnose): :mod:`.problem` (datasets, prior features, constraints) -> :mod:`.search` (SNGP runs)
-> :mod:`.ladder` (guards, the final rung) -> :mod:`.result` (the typed result, result.json);
:mod:`.pipeline` composes them; :mod:`.study` repeats it over variants."""
