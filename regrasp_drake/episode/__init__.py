"""What runs an episode on the station (station/ holds the hardware: plant,
sensors, servos, state machine, monitor): `episode` (one episode held and
run in stages, `Episode`: start, advance to the release, set the task,
advance to the outcome, read the result; `run_episode`, the stages in one
call; and how it advances: to the release time and over to the catch's
step, on from a kept throw, to the outcome), `diagram` (what it simulates:
the station and the catch controller wired with the loggers and Meshcat;
its simulator, and the state carried to another plant step), `result`
(what it came to, and its logs), `branching` (a map's cells forked from
one shared episode) and `replay` (Meshcat's recording)."""
