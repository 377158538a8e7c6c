"""What runs an episode on the station (station/ holds the hardware: plant,
sensors, servos, state machine, monitor): `episode` (one episode held and
run in stages, `Episode`: build, advance to the release, set the task,
advance to the outcome, read the result; `run_episode`, the stages in one
call), `diagram` (the episode's diagram: the station and the catch
controller wired with the loggers and Meshcat; its simulator, and the
handover to another plant step), `simulate` (advancing it: to the outcome,
to the release time and over to the catch's step, on from a kept throw),
`result` (what it came to), `branching` (a map's cells forked from one
shared episode) and `replay` (Meshcat's recording)."""
