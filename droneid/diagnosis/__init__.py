"""Residual -> the physical effect a prior lacks: :mod:`.diagnose` composes the effect models
(:mod:`.effect_model`) and the open-ended search (:mod:`.residual_search`) into a
:class:`~droneid.diagnosis.result.DiagnosisResult` (:mod:`.result`)."""
