"""What runs an episode on the station (station/ holds the hardware: plant,
sensors, servos, state machine, monitor): `run` (one episode: build,
initialise, hand over, advance, read its result), `simulate` (advancing it:
to the outcome, to the release time and over to the catch's step, on from a
kept throw), `branching` (a map's cells forked from one shared throw) and
`replay` (Meshcat's recording)."""
