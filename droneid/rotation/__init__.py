"""The rotational model (ω̇, body FLU): the rigid body and its terms (:mod:`.model`), the rate
decay (:mod:`.decay`), hold-one-flight-out folds (:mod:`.folds`), the ladder on the one decision
rule (:mod:`.ladder`), the per-axis choice (:mod:`.choice`) and identify's stage (:mod:`.stage`)."""
