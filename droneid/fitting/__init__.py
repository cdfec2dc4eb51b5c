"""Fits and the decisions on them: the one calibrated decision rule (:mod:`.decide`), physical
terms fitted with intervals (:mod:`.terms`), the thrust curve from commands
(:mod:`.thrust_curve`), the constancy test across flights (:mod:`.constancy`), the physics guards
on evolved terms (:mod:`.physics_guard`), the closed-form model (:mod:`.closed_form`) and the
verdict a user reads (:mod:`.verdict`)."""
