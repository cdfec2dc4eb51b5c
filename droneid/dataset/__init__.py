"""Flight -> Dataset: derivative targets and input columns (:mod:`.builder`, :mod:`.data`),
multi-stream alignment (:mod:`.align`), (flight, block) validation units (:mod:`.validation`),
and whether a flight's signals suit a prior (:mod:`.suitability`)."""
