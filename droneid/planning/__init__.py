"""What identify and diagnose both run under, made once: the settings (:mod:`.settings`:
:class:`~droneid.planning.settings.IdentifyConfig`, every knob validated once) and the plan
(:mod:`.plan`: the prior and why, the thrust curve from commands, the thrust inputs' offset with
its block test, the held-out cuts), chosen on the training flights only. The same flights give
the same plan in both commands."""
