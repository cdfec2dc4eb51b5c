"""Driving the SNGP engine without importing it until needed: :mod:`.runner` runs independent
jobs in this process, on local workers or on a Dask cluster (with the engine's one-time compile
and its progress), and :mod:`.fit` is ``droneid fit``'s pipeline (SNGP on a CSV table, with
priors and constraints). Light to import: ``droneid.sngp`` (numba) loads on first use."""
