"""Flight-log readers and writers. Every reader returns one :class:`droneid.flight.Flight`
in droneid's internal convention (see :mod:`droneid.frames`)."""
