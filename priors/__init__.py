"""Prior models (empirical equations as prior features), formal constraint sets, and the
catalogue of candidate effects used by the diagnosis."""
