"""The one :class:`~droneid.logs.flight.Flight` every reader returns, and what droneid checks on
it before any model: in-flight detection (:mod:`.in_flight`), sample screening
(:mod:`.screening`), the vehicle's evidence (:mod:`.vehicle_evidence`) and the frame/unit
convention checks (:mod:`.consistency` on the grid helpers of :mod:`.signal_grid`)."""
