"""Using an identified model: :mod:`.predict` (v̇ and simulated states on other logs, their
errors), :mod:`.export` (self-contained Python, C, MATLAB, LaTeX) and :mod:`.vehicle_export`
(the whole vehicle, flown from its motor speeds)."""
