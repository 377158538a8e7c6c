"""What runs an episode on the station (station/ holds the hardware: plant,
sensors, servos, state machine, monitor): `run` (build, initialise, hand
over at the release, advance to the outcome, read), `branching` (a map's
cells forked from one shared throw) and `replay` (Meshcat's recording)."""
