"""freqid_casadi: stable, minimum-phase low-order models with delay from frequency data."""
